import json

import redis
from django import forms
from django.contrib import admin, messages
from django.db import transaction
from django.db.models import QuerySet
from django.http import HttpRequest

from onboard.envelope import EnvelopeError, parse_envelope, parse_latlon
from workers.counters import snapshot

from . import credentials, envelopes
from .identity import (
    EU_CATEGORIES,
    EU_CLASSES,
    UA_TYPES,
    IdentityError,
    check_eu_declaration,
    parse_operator_id,
    parse_serial_number,
)
from .models import CommandLog, ConnectionEvent, Drone, Membership, Organisation


class MembershipInline(admin.TabularInline):
    model = Membership
    extra = 0
    autocomplete_fields = ["user"]


class OrganisationForm(forms.ModelForm):
    class Meta:
        model = Organisation
        fields = ["name", "slug", "envelope", "operator_id", "require_remote_id"]

    def clean_operator_id(self) -> str:
        """EN 4709-002 (with its secret characters) or FAA; the stored public part stays."""
        value = self.cleaned_data.get("operator_id") or ""
        if value == self.instance.operator_id:
            return value
        try:
            return parse_operator_id(value)
        except IdentityError as exc:
            raise forms.ValidationError(exc.message) from None

    def clean_envelope(self) -> dict:
        """The flight envelope's own checks (onboard/envelope.py), naming the bad field."""
        data = self.cleaned_data["envelope"] or {}
        try:
            if not isinstance(data, dict):
                raise EnvelopeError("envelope", "must be a JSON object")
            home = data.get("home")
            parse_envelope(data, home=None if home is None else parse_latlon(home, "home"))
        except EnvelopeError as exc:
            raise forms.ValidationError(f"{exc.field}: {exc.message}") from None
        return data


@admin.register(Organisation)
class OrganisationAdmin(admin.ModelAdmin):
    form = OrganisationForm
    list_display = ["name", "slug", "created_at"]
    search_fields = ["name", "slug"]
    prepopulated_fields = {"slug": ["name"]}
    inlines = [MembershipInline]

    def save_model(self, request, obj, form, change):  # type: ignore[no-untyped-def]
        super().save_model(request, obj, form, change)
        if {"envelope", "operator_id"} & set(form.changed_data):
            drones = list(obj.drones.select_related("organisation"))
            transaction.on_commit(lambda: envelopes.send_to_drones(drones))


def _send_drone_envelope(drone: Drone, changed: list[str]) -> None:
    identity = {"serial_number", "ua_type", "eu_category", "eu_class"}
    if {"max_height", "max_distance", *identity} & set(changed):
        transaction.on_commit(lambda: envelopes.send_to_drones([drone]))


@admin.register(Membership)
class MembershipAdmin(admin.ModelAdmin):
    list_display = ["user", "organisation", "role", "created_at"]
    list_filter = ["role", "organisation"]
    search_fields = ["user__username", "organisation__name"]
    autocomplete_fields = ["user", "organisation"]


class ConnectionEventInline(admin.TabularInline):
    model = ConnectionEvent
    extra = 0
    readonly_fields = ["kind", "at", "reason"]
    can_delete = False
    max_num = 0
    ordering = ["-at"]


class DroneForm(forms.ModelForm):
    class Meta:
        model = Drone
        # The admin shows every field; these are the ones this form checks.
        fields = [
            "organisation",
            "drone_id",
            "name",
            "max_height",
            "max_distance",
            "serial_number",
            "remote_id_external",
            "ua_type",
            "eu_category",
            "eu_class",
        ]
        widgets = {
            field: forms.Select(choices=[(n, name) for name, n in names.items()])
            for field, names in (
                ("ua_type", UA_TYPES),
                ("eu_category", EU_CATEGORIES),
                ("eu_class", EU_CLASSES),
            )
        }

    def clean_serial_number(self) -> str:
        try:
            return parse_serial_number(self.cleaned_data.get("serial_number") or "")
        except IdentityError as exc:
            raise forms.ValidationError(exc.message) from None

    def clean(self) -> dict:
        """A drone's own height and distance limits may only lower its organisation's."""
        data = super().clean()
        self._check_declared(data)
        organisation = data.get("organisation")
        if organisation is None:
            return data
        limits = envelopes.organisation_envelope(organisation)
        for name in ("max_height", "max_distance"):
            value = data.get(name)
            if value is not None and not 0 < value <= getattr(limits, name):
                self.add_error(
                    name,
                    f"must be above 0 and at most the organisation's {getattr(limits, name):g} m",
                )
        return data

    def _check_declared(self, data: dict) -> None:
        """The UA type, EU category and class are Open Drone ID numbers that fit together;
        one the form left out keeps the drone's value."""
        values = {}
        for field, names in (
            ("ua_type", UA_TYPES),
            ("eu_category", EU_CATEGORIES),
            ("eu_class", EU_CLASSES),
        ):
            value = data.get(field)
            values[field] = getattr(self.instance, field) if value is None else value
            if values[field] not in names.values():
                self.add_error(field, "not a value the broadcast knows")
                return
        try:
            check_eu_declaration(values["eu_category"], values["eu_class"])
        except IdentityError as exc:
            self.add_error(exc.field, exc.message)


@admin.register(Drone)
class DroneAdmin(admin.ModelAdmin):
    form = DroneForm
    list_display = [
        "drone_id",
        "organisation",
        "online",
        "armed",
        "airborne",
        "battery_remaining",
        "last_seen",
        "credentials_revoked",
    ]
    list_filter = ["organisation", "online", "armed", "airborne", "credentials_revoked"]
    search_fields = ["drone_id", "name"]
    readonly_fields = ["mqtt_password_hash", "last_seen", "created_at"]
    inlines = [ConnectionEventInline]
    actions = ["issue_credentials", "revoke_credentials"]
    change_list_template = "fleet/admin/drone_change_list.html"

    def save_model(self, request, obj, form, change):  # type: ignore[no-untyped-def]
        super().save_model(request, obj, form, change)
        _send_drone_envelope(obj, form.changed_data)

    @admin.action(description="Issue new broker credentials (shown once)")
    def issue_credentials(self, request: HttpRequest, queryset: QuerySet[Drone]) -> None:
        # One broker update for the whole selection (provision_many), not one per drone.
        ids = list(queryset.order_by("drone_id").values_list("drone_id", flat=True))
        try:
            issued = credentials.provision_many(ids)
        except credentials.BrokerUnavailable as exc:
            self.message_user(request, f"No credentials issued: {exc}", messages.ERROR)
            return
        for one in issued:
            self.message_user(
                request,
                f"{one.drone_id}: {json.dumps(one.to_dict())} — copy it now, it is not kept.",
                messages.WARNING,
            )

    @admin.action(description="Revoke broker credentials (disconnects the drone)")
    def revoke_credentials(self, request: HttpRequest, queryset: QuerySet[Drone]) -> None:
        drones = list(queryset)
        try:
            credentials.revoke_many(drones)
        except credentials.BrokerUnavailable as exc:
            self.message_user(
                request,
                f"Revoked {len(drones)} drone(s) in the database, but the broker was not "
                f"updated ({exc}); run `manage.py provision_drone --sync` once it is back.",
                messages.ERROR,
            )
            return
        self.message_user(request, f"Revoked {len(drones)} drone(s).", messages.SUCCESS)

    def changelist_view(self, request: HttpRequest, extra_context: dict | None = None):  # type: ignore[no-untyped-def]
        """Gateway counters (received, handled, dropped by reason) above the drone list."""
        try:
            processes = snapshot()
        except redis.RedisError:
            processes = {}
        gateways = {
            name: sorted((k, int(v)) for k, v in counts.items() if k != "updated_at")
            for name, counts in processes.items()
            if name.startswith("gateway")
        }
        extra_context = {**(extra_context or {}), "gateway_counters": gateways}
        return super().changelist_view(request, extra_context)


@admin.register(ConnectionEvent)
class ConnectionEventAdmin(admin.ModelAdmin):
    list_display = ["drone", "kind", "at", "reason"]
    list_filter = ["kind", "drone__organisation"]
    search_fields = ["drone__drone_id"]
    date_hierarchy = "at"


@admin.register(CommandLog)
class CommandLogAdmin(admin.ModelAdmin):
    list_display = ["command", "drone", "user", "outcome", "sent_at", "answered_at"]
    list_filter = ["outcome", "command", "drone__organisation"]
    search_fields = ["drone__drone_id", "request_id", "user__username"]
    date_hierarchy = "sent_at"
    readonly_fields = [f.name for f in CommandLog._meta.fields]
