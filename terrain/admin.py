"""Importing terrain from the admin: upload an SRTM .hgt file, a GeoTIFF or a ZIP of them
(at most TERRAIN_UPLOAD_MAX_BYTES, from a staff user the admin lets add terrain tiles:
checked before the body is read, config/uploadgate.py). It is read completely, within the
import limits of terrain/sources.py, before anything is kept."""

from __future__ import annotations

import re
import shutil
import uuid
from pathlib import Path

from django import forms
from django.conf import settings
from django.contrib import admin, messages
from django.core.exceptions import PermissionDenied
from django.http import HttpRequest, HttpResponse, HttpResponseRedirect
from django.template.response import TemplateResponse
from django.urls import reverse

from terrain import importer, store
from terrain.formats import TerrainError
from terrain.models import TerrainClearance, TerrainTile

# The admin's import form posts here; config/asgi.py refuses strangers and bodies over the
# limit before Django reads them.
TERRAIN_UPLOAD_PATH = "/admin/terrain/terraintile/add/"
SAFE_NAME = re.compile(r"[^A-Za-z0-9._-]")


def terrain_upload_limit() -> int:
    return int(settings.TERRAIN_UPLOAD_MAX_BYTES)


class TerrainUploadForm(forms.Form):
    file = forms.FileField(
        help_text="An SRTM .hgt file (named like N38W010.hgt), a GeoTIFF, or a .zip of them."
    )

    def clean_file(self):  # type: ignore[no-untyped-def]
        upload = self.cleaned_data["file"]
        limit = terrain_upload_limit()
        if upload.size > limit:
            raise forms.ValidationError(f"The file is larger than the limit of {limit} bytes.")
        return upload


def _spool(upload) -> Path:  # type: ignore[no-untyped-def]
    """The upload as a file under its own (sanitised) name: an SRTM tile's name says where
    it lies."""
    folder = store.incoming_dir() / f"upload-{uuid.uuid4().hex}"
    folder.mkdir(parents=True)
    path = folder / (SAFE_NAME.sub("_", Path(upload.name or "upload").name)[:200] or "upload")
    with path.open("wb") as out:
        for chunk in upload.chunks():
            out.write(chunk)
    return path


def import_upload(upload) -> importer.Imported:  # type: ignore[no-untyped-def]
    """Import an uploaded file whole or not at all; TerrainError names what is wrong."""
    path = _spool(upload)
    try:
        return importer.import_path(path, source=upload.name or path.name)
    finally:
        shutil.rmtree(path.parent, ignore_errors=True)


@admin.register(TerrainTile)
class TerrainTileAdmin(admin.ModelAdmin):
    list_display = ("name", "kind", "south", "north", "west", "east", "resolution_arcsec",
                    "void_count", "created_at")  # fmt: skip
    readonly_fields = ("name", "source", "kind", "west", "south", "east", "north", "rows",
                       "cols", "cell_lat", "cell_lon", "void_count", "created_at")  # fmt: skip

    def has_change_permission(self, request, obj=None) -> bool:  # type: ignore[no-untyped-def]
        return False

    def add_view(self, request: HttpRequest, form_url: str = "", extra_context=None) -> HttpResponse:  # type: ignore[no-untyped-def]  # fmt: skip
        """The import form instead of a model form: one upload may hold many tiles."""
        if not self.has_add_permission(request):
            raise PermissionDenied
        form = TerrainUploadForm(request.POST or None, request.FILES or None)
        if request.method == "POST" and form.is_valid():
            try:
                imported = import_upload(form.cleaned_data["file"])
            except TerrainError as exc:
                form.add_error("file", str(exc))
            else:
                self._report(request, imported)
                return HttpResponseRedirect(reverse("admin:terrain_terraintile_changelist"))
        context = {
            **self.admin_site.each_context(request),
            "opts": self.model._meta,
            "title": "Import terrain",
            "form": form,
            "limit": terrain_upload_limit(),
        }
        return TemplateResponse(request, "admin/terrain/terraintile/import.html", context)

    def _report(self, request: HttpRequest, imported: importer.Imported) -> None:
        for tile in imported.tiles:
            messages.success(request, f"Imported {tile} with {tile.void_count} voids.")
        for overlap in imported.overlaps:
            messages.warning(request, f"Overlap: {overlap}; the newest import is used there.")

    def delete_model(self, request, obj) -> None:  # type: ignore[no-untyped-def]
        importer.delete_tiles([obj])
        super().delete_model(request, obj)

    def delete_queryset(self, request, queryset) -> None:  # type: ignore[no-untyped-def]
        importer.delete_tiles(list(queryset))
        super().delete_queryset(request, queryset)


@admin.register(TerrainClearance)
class TerrainClearanceAdmin(admin.ModelAdmin):
    list_display = ("organisation", "min_clearance", "ceiling_above_terrain")
