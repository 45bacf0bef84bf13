"""The admin: zones and authorisations, and the zone file upload (staff only)."""

from __future__ import annotations

from django import forms
from django.conf import settings
from django.contrib import admin, messages
from django.http import HttpRequest, HttpResponse, HttpResponseRedirect
from django.template.response import TemplateResponse
from django.urls import path, reverse

from fleet.models import Organisation

from .formats.common import ZoneFileError
from .models import Authorisation, Zone
from .store import import_bytes

IMPORT_PATH = "import/"
# The upload's full address: config/uploadgate.py admits its body only from staff with the
# right to add zones.
ZONES_UPLOAD_PATH = f"/admin/zones/zone/{IMPORT_PATH}"


class ZoneFileForm(forms.Form):
    file = forms.FileField(help_text="GeoJSON, EUROCAE ED-269 JSON or KML")
    organisation = forms.ModelChoiceField(
        Organisation.objects.all(), required=False, help_text="empty: site-wide"
    )
    source = forms.CharField(max_length=200, required=False, help_text="default: file name")

    def clean_file(self):  # type: ignore[no-untyped-def]
        upload = self.cleaned_data["file"]
        if upload.size > settings.ZONES_MAX_FILE_BYTES:
            raise forms.ValidationError(f"Larger than {settings.ZONES_MAX_FILE_BYTES} bytes.")
        return upload


@admin.register(Zone)
class ZoneAdmin(admin.ModelAdmin):
    list_display = ("identifier", "part", "name", "restriction", "organisation", "source")
    list_filter = ("restriction", "file_format", "organisation")
    search_fields = ("identifier", "name")
    readonly_fields = ("imported_at",)
    change_list_template = "admin/zones/zone/change_list.html"

    def get_urls(self):  # type: ignore[no-untyped-def]
        upload = self.admin_site.admin_view(self.import_view)
        return [path(IMPORT_PATH, upload, name="zones_zone_import"), *super().get_urls()]

    def has_change_permission(self, request: HttpRequest, obj: object = None) -> bool:
        return False  # a zone changes only by importing its publisher's file again

    def add_view(self, request: HttpRequest, form_url: str = "", extra_context=None):  # type: ignore[no-untyped-def]
        """Zones are added by importing a file, whose every zone is checked."""
        return HttpResponseRedirect(reverse("admin:zones_zone_import"))

    def import_view(self, request: HttpRequest) -> HttpResponse:
        """Staff with the right to add zones upload a file; a refused one changes nothing."""
        if not self.has_add_permission(request):
            return HttpResponse("Forbidden", status=403)
        form = ZoneFileForm(request.POST or None, request.FILES or None)
        if request.method == "POST" and form.is_valid():
            data = form.cleaned_data
            try:
                done = import_bytes(
                    data["file"].name, data["file"].read(), data["organisation"], data["source"]
                )
            except ZoneFileError as exc:
                form.add_error("file", f"Refused, nothing imported: {exc}")
            else:
                self.message_user(
                    request, f"Imported {done.zones} zones ({done.file_format}).", messages.SUCCESS
                )
                return HttpResponseRedirect(reverse("admin:zones_zone_changelist"))
        context = {**self.admin_site.each_context(request), "form": form, "title": "Import zones"}
        return TemplateResponse(request, "admin/zones/zone/import.html", context)


@admin.register(Authorisation)
class AuthorisationAdmin(admin.ModelAdmin):
    """Shown only: authorisations are recorded by an organisation's admin through the API."""

    list_display = ("reference", "zone", "organisation", "issued_by", "expires_at", "recorded_by")
    list_filter = ("organisation",)

    def has_add_permission(self, request: HttpRequest) -> bool:
        return False

    def has_change_permission(self, request: HttpRequest, obj: object = None) -> bool:
        return False
