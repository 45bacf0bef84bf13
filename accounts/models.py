"""Personal API tokens."""

from __future__ import annotations

from django.conf import settings
from django.db import models
from django.utils import timezone


class ApiToken(models.Model):
    """A personal API token. Only its SHA-256 is kept; the key is shown once."""

    class Scope(models.TextChoices):
        READ = "read", "Read-only"
        OPERATE = "operate", "Operate"

    user = models.ForeignKey(
        settings.AUTH_USER_MODEL, on_delete=models.CASCADE, related_name="api_tokens"
    )
    # The organisation the token was made for: it reaches that one only (fleet.tenancy),
    # and leaving it revokes the token. Empty only on tokens made before tokens were
    # bound: they act for every organisation of the user until they expire.
    organisation = models.ForeignKey(
        "fleet.Organisation", null=True, blank=True, on_delete=models.CASCADE, related_name="+"
    )
    name = models.CharField(max_length=80)
    scope = models.CharField(max_length=8, choices=Scope.choices, default=Scope.OPERATE)
    key_hash = models.CharField(max_length=64, unique=True)
    prefix = models.CharField(max_length=16)
    created_at = models.DateTimeField(auto_now_add=True)
    expires_at = models.DateTimeField()
    last_used_at = models.DateTimeField(null=True, blank=True)
    revoked_at = models.DateTimeField(null=True, blank=True)

    class Meta:
        ordering = ["-created_at"]

    def __str__(self) -> str:
        return f"{self.name} ({self.prefix}…) of {self.user}"

    @property
    def state(self) -> str:
        """`revoked`, `expired` or `active`."""
        if self.revoked_at is not None:
            return "revoked"
        return "expired" if self.expires_at <= timezone.now() else "active"

    @property
    def read_only(self) -> bool:
        return self.scope == self.Scope.READ


class Invitation(models.Model):
    """An invitation by e-mail to join an organisation with a role; used once.

    The link carries a random key whose SHA-256 is stored, so an invitation can be
    listed, revoked and refused once used, which a stateless signed link cannot be.
    """

    organisation = models.ForeignKey(
        "fleet.Organisation", on_delete=models.CASCADE, related_name="invitations"
    )
    email = models.EmailField()
    role = models.CharField(max_length=16)
    key_hash = models.CharField(max_length=64, unique=True)
    invited_by = models.ForeignKey(
        settings.AUTH_USER_MODEL, null=True, on_delete=models.SET_NULL, related_name="+"
    )
    created_at = models.DateTimeField(auto_now_add=True)
    expires_at = models.DateTimeField()
    accepted_at = models.DateTimeField(null=True, blank=True)
    accepted_by = models.ForeignKey(
        settings.AUTH_USER_MODEL, null=True, blank=True, on_delete=models.SET_NULL, related_name="+"
    )
    revoked_at = models.DateTimeField(null=True, blank=True)

    class Meta:
        ordering = ["-created_at"]

    def __str__(self) -> str:
        return f"{self.email} → {self.organisation} ({self.role})"

    @property
    def state(self) -> str:
        """`accepted`, `revoked`, `expired` or `pending`."""
        if self.accepted_at is not None:
            return "accepted"
        if self.revoked_at is not None:
            return "revoked"
        return "expired" if self.expires_at <= timezone.now() else "pending"


class AuditQuerySet(models.QuerySet):
    """Append-only: rows are added, never changed or deleted through the ORM."""

    def update(self, **kwargs: object) -> int:
        raise PermissionError("the audit trail is append-only")

    def delete(self) -> tuple[int, dict[str, int]]:
        raise PermissionError("the audit trail is append-only")


class AuditEvent(models.Model):
    """Who did what, when, from where, and how it ended, in one organisation."""

    class Kind(models.TextChoices):
        COMMAND = "command", "Command"
        MISSION = "mission", "Mission"
        ENVELOPE = "envelope", "Envelope"
        MEMBER = "member", "Member"
        TOKEN = "token", "Token"
        SECURITY = "security", "Sign-in security"
        ORGANISATION = "organisation", "Organisation settings"
        MAINTENANCE = "maintenance", "Maintenance"

    organisation = models.ForeignKey(
        "fleet.Organisation", on_delete=models.CASCADE, related_name="audit_events"
    )
    at = models.DateTimeField(default=timezone.now, db_index=True)
    actor = models.ForeignKey(
        settings.AUTH_USER_MODEL, null=True, blank=True, on_delete=models.SET_NULL, related_name="+"
    )
    # Kept when the account is deleted later.
    actor_name = models.CharField(max_length=150, blank=True)
    kind = models.CharField(max_length=16, choices=Kind.choices)
    action = models.CharField(max_length=60)
    target = models.CharField(max_length=200, blank=True)
    outcome = models.CharField(max_length=16)
    ip = models.GenericIPAddressField(null=True, blank=True)
    detail = models.JSONField(default=dict, blank=True)

    objects = AuditQuerySet.as_manager()

    class Meta:
        ordering = ["-at", "-id"]
        indexes = [models.Index(fields=["organisation", "-at"])]

    def __str__(self) -> str:
        return f"{self.at:%Y-%m-%d %H:%M:%S} {self.actor_name} {self.action} {self.target}"

    def save(self, *args: object, **kwargs: object) -> None:
        if self.pk is not None:
            raise PermissionError("the audit trail is append-only")
        super().save(*args, **kwargs)  # type: ignore[arg-type]

    def delete(self, *args: object, **kwargs: object) -> tuple[int, dict[str, int]]:
        raise PermissionError("the audit trail is append-only")


class SignInAttempt(models.Model):
    """One sign-in, successful or not, for the user's own security page."""

    user = models.ForeignKey(
        settings.AUTH_USER_MODEL,
        null=True,
        blank=True,
        on_delete=models.CASCADE,
        related_name="sign_in_attempts",
    )
    username = models.CharField(max_length=150)
    at = models.DateTimeField(default=timezone.now)
    succeeded = models.BooleanField()
    # What was checked: `password`, `one-time code`, or `password and one-time code`.
    method = models.CharField(max_length=40)
    ip = models.GenericIPAddressField(null=True, blank=True)
    user_agent = models.CharField(max_length=200, blank=True)

    class Meta:
        ordering = ["-at", "-id"]
        indexes = [models.Index(fields=["user", "-at"]), models.Index(fields=["at"])]

    def __str__(self) -> str:
        state = "ok" if self.succeeded else "failed"
        return f"{self.username} {state} at {self.at:%Y-%m-%d %H:%M:%S}"


class OrganisationSettings(models.Model):
    """What an organisation's admins set for it beyond its name and envelope."""

    organisation = models.OneToOneField(
        "fleet.Organisation", on_delete=models.CASCADE, related_name="account_settings"
    )
    # Operators and admins must sign in with a one-time code before changing anything.
    require_second_factor = models.BooleanField(default=False)
    # [lat, lon] the organisation's maps and new plans start from; null: none set.
    default_home = models.JSONField(null=True, blank=True)
    # E-mail addresses and webhook URLs alerts go to.
    alert_recipients = models.JSONField(default=list, blank=True)

    def __str__(self) -> str:
        return f"settings of {self.organisation}"
