"""Organisations, their members and roles, and their drones."""

from __future__ import annotations

import re

from django.conf import settings
from django.core.exceptions import ValidationError
from django.core.validators import RegexValidator
from django.db import models
from django.utils import timezone

from .identity import required_by_default

DRONE_ID_RE = re.compile(r"^[A-Za-z0-9_-]{1,64}$")
# Broker accounts that are not drones: a drone's broker username is its id, so a drone
# named like one would share (or take over) its account. RabbitMQ ships `admin`/`guest`.
RESERVED_BROKER_USERS = ("ground", "admin", "guest")


def reserved_drone_ids() -> set[str]:
    """Names no drone may take, lower-cased: the broker's own accounts and the ground's
    service users (MQTT_SERVICE_USERS)."""
    return {name.lower() for name in (*RESERVED_BROKER_USERS, *settings.MQTT_SERVICE_USERS)}


def validate_not_reserved(drone_id: str) -> None:
    """Refuse a reserved broker account name as a drone id, whatever its case."""
    if str(drone_id).lower() in reserved_drone_ids():
        raise ValidationError(
            f"{drone_id!r} is reserved for the broker's own accounts; choose another drone id.",
            code="reserved",
        )


class Organisation(models.Model):
    name = models.CharField(max_length=120)
    slug = models.SlugField(unique=True)
    created_at = models.DateTimeField(auto_now_add=True)
    # The flight envelope (onboard/envelope.py's JSON form); empty means the defaults.
    envelope = models.JSONField(default=dict, blank=True)
    # Remote ID (docs/remote-id.md): the operator registration number as broadcast (EU:
    # its 16 public characters; FAA), and whether drones may fly without an identity.
    operator_id = models.CharField(max_length=20, blank=True, default="", db_default="")
    require_remote_id = models.BooleanField(default=required_by_default, db_default=True)

    class Meta:
        ordering = ["name"]

    def __str__(self) -> str:
        return self.name

    @property
    def group_name(self) -> str:
        """The Channels group every page of this organisation listens on."""
        return f"org-{self.pk}"


class Role(models.TextChoices):
    VIEWER = "viewer", "Viewer"
    OPERATOR = "operator", "Operator"
    ADMIN = "admin", "Admin"


ROLE_RANK = {Role.VIEWER: 0, Role.OPERATOR: 1, Role.ADMIN: 2}


class MembershipQuerySet(models.QuerySet):
    def for_user(self, user) -> MembershipQuerySet:  # type: ignore[no-untyped-def]
        if not user.is_authenticated:
            return self.none()
        from .tenancy import reach  # here: tenancy imports these models

        return self.filter(reach(user, via="")).select_related("organisation")


class Membership(models.Model):
    user = models.ForeignKey(
        settings.AUTH_USER_MODEL, on_delete=models.CASCADE, related_name="memberships"
    )
    organisation = models.ForeignKey(
        Organisation, on_delete=models.CASCADE, related_name="memberships"
    )
    role = models.CharField(max_length=16, choices=Role.choices, default=Role.VIEWER)
    created_at = models.DateTimeField(auto_now_add=True)

    objects = MembershipQuerySet.as_manager()

    class Meta:
        constraints = [
            models.UniqueConstraint(fields=["user", "organisation"], name="one_membership_per_org")
        ]
        ordering = ["organisation__name"]

    def __str__(self) -> str:
        return f"{self.user} @ {self.organisation} ({self.role})"

    def allows(self, role: str) -> bool:
        return ROLE_RANK[Role(self.role)] >= ROLE_RANK[Role(role)]


class DroneQuerySet(models.QuerySet):
    def for_user(self, user) -> DroneQuerySet:  # type: ignore[no-untyped-def]
        """Only drones of organisations the user belongs to: the isolation rule."""
        if not user.is_authenticated:
            return self.none()
        from .tenancy import reach  # here: tenancy imports these models

        return self.filter(reach(user))


class LogCollection(models.TextChoices):
    """When a drone uploads its logs after landing (onboard/collect.py): on every link, only
    on Wi-Fi or wired ground links, or never. Sent to the drone with its envelope."""

    ALWAYS = "always", "Always"
    GROUND_LINKS = "ground_links", "Only on Wi-Fi or ground links"
    OFF = "off", "Off"


class Drone(models.Model):
    organisation = models.ForeignKey(Organisation, on_delete=models.CASCADE, related_name="drones")
    # Topic trees are global on the broker, so the id is unique across organisations.
    drone_id = models.CharField(
        max_length=64,
        unique=True,
        validators=[RegexValidator(DRONE_ID_RE.pattern), validate_not_reserved],
    )
    name = models.CharField(max_length=120, blank=True)

    online = models.BooleanField(default=False)
    last_seen = models.DateTimeField(null=True, blank=True)
    lat = models.FloatField(null=True, blank=True)
    lon = models.FloatField(null=True, blank=True)
    alt = models.FloatField(null=True, blank=True)
    battery_voltage = models.FloatField(null=True, blank=True)
    battery_remaining = models.FloatField(null=True, blank=True)
    armed = models.BooleanField(default=False)
    airborne = models.BooleanField(default=False)
    flight_mode = models.CharField(max_length=40, blank=True)
    mission = models.JSONField(null=True, blank=True)
    fc = models.JSONField(null=True, blank=True)
    specs = models.JSONField(default=dict, blank=True)
    sensors = models.JSONField(default=dict, blank=True)
    # Remote ID (docs/remote-id.md): the ANSI/CTA-2063-A serial number it broadcasts, and
    # whether an admin declared an external broadcast module fitted (drones whose flight
    # controller speaks no Open Drone ID); who declared it and when is in the audit trail.
    serial_number = models.CharField(max_length=20, blank=True, default="", db_default="")
    remote_id_external = models.BooleanField(default=False, db_default=False)
    # What the broadcast declares of the aircraft (fleet.identity: UA_TYPES, EU_CATEGORIES,
    # EU_CLASSES, as Open Drone ID numbers them): a multirotor, EU category and class
    # undeclared until an admin sets them; a form that leaves them out keeps them.
    ua_type = models.PositiveSmallIntegerField(default=2, db_default=2, blank=True)
    eu_category = models.PositiveSmallIntegerField(default=0, db_default=0, blank=True)
    eu_class = models.PositiveSmallIntegerField(default=0, db_default=0, blank=True)
    # Whether the drone uploads its logs after landing, set by operators (logs/policy.py).
    log_collection = models.CharField(
        max_length=16,
        choices=LogCollection.choices,
        default=LogCollection.ALWAYS,
        db_default=LogCollection.ALWAYS,
    )

    # The drone's own envelope limits; they can only lower the organisation's.
    max_height = models.FloatField(null=True, blank=True)
    max_distance = models.FloatField(null=True, blank=True)
    # Where the ground last saw the drone at rest ([lat, lon]), and the last target the
    # drone accepted from the ground (NED metres from that home): the envelope check's start.
    home = models.JSONField(null=True, blank=True)
    nav_target = models.JSONField(null=True, blank=True)

    # Broker credentials: the username is the drone id; only a hash is kept.
    mqtt_password_hash = models.CharField(max_length=255, blank=True)
    credentials_revoked = models.BooleanField(default=False)

    created_at = models.DateTimeField(auto_now_add=True)

    objects = DroneQuerySet.as_manager()

    class Meta:
        ordering = ["drone_id"]
        indexes = [models.Index(fields=["organisation", "online"])]

    def __str__(self) -> str:
        return self.drone_id

    @property
    def position(self) -> dict | None:
        if self.lat is None or self.lon is None:
            return None
        return {"lat": self.lat, "lon": self.lon, "alt": self.alt}

    @property
    def battery(self) -> dict | None:
        if self.battery_voltage is None and self.battery_remaining is None:
            return None
        return {"voltage": self.battery_voltage, "remaining": self.battery_remaining}


class ConnectionEvent(models.Model):
    class Kind(models.TextChoices):
        ONLINE = "online", "Online"
        OFFLINE = "offline", "Offline"

    drone = models.ForeignKey(Drone, on_delete=models.CASCADE, related_name="connection_events")
    kind = models.CharField(max_length=8, choices=Kind.choices)
    at = models.DateTimeField()
    reason = models.CharField(max_length=200, blank=True)

    class Meta:
        ordering = ["-at"]
        indexes = [models.Index(fields=["drone", "-at"])]

    def __str__(self) -> str:
        return f"{self.drone} {self.kind} at {self.at:%Y-%m-%d %H:%M:%S}"


class CommandLog(models.Model):
    """Every command sent to a drone, who sent it, and how it ended."""

    class Outcome(models.TextChoices):
        PENDING = "pending", "Pending"
        OK = "ok", "OK"
        FAILED = "failed", "Failed"
        TIMEOUT = "timeout", "Timed out"
        REJECTED = "rejected", "Rejected before sending"

    drone = models.ForeignKey(Drone, on_delete=models.CASCADE, related_name="commands")
    user = models.ForeignKey(
        settings.AUTH_USER_MODEL, null=True, blank=True, on_delete=models.SET_NULL
    )
    request_id = models.CharField(max_length=32, db_index=True)
    command = models.CharField(max_length=40)
    params = models.JSONField(default=dict, blank=True)
    outcome = models.CharField(max_length=10, choices=Outcome.choices, default=Outcome.PENDING)
    response = models.JSONField(null=True, blank=True)
    error = models.TextField(blank=True)
    # When it left, set by the sender: the entry may be written after its answer.
    sent_at = models.DateTimeField(default=timezone.now, editable=False)
    answered_at = models.DateTimeField(null=True, blank=True)

    class Meta:
        ordering = ["-sent_at"]

    def __str__(self) -> str:
        return f"{self.command} → {self.drone} ({self.outcome})"
