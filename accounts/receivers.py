"""Signal receivers: what other apps do, seen from the accounts app without them
importing it (the fleet and missions apps know nothing of accounts)."""

from __future__ import annotations

from typing import Any

from django.conf import settings
from django.contrib.auth.signals import user_logged_in, user_login_failed
from django.db.models.signals import post_save

from fleet.signals import action_refused, envelope_changed
from fleet.signals import identity_changed as fleet_identity_changed

from . import admin_site, audit, passwords, signin

# The command log's outcomes, as the audit trail names them.
COMMAND_OUTCOMES = {"ok": "ok", "failed": "failed", "timeout": "timeout", "rejected": "refused"}


def command_logged(sender: Any, instance: Any, **kwargs: Any) -> None:
    """A command entry reached its outcome (refused before sending, or answered)."""
    if instance.outcome not in COMMAND_OUTCOMES:
        return
    audit.record(
        instance.drone.organisation_id,
        audit.Kind.COMMAND,
        f"command.{instance.command}",
        target=instance.drone.drone_id,
        outcome=COMMAND_OUTCOMES[instance.outcome],
        actor=instance.user,
        detail={
            "params": instance.params,
            "request_id": instance.request_id,
            "error": instance.error,
        },
    )


def _mission_action(event: Any) -> str | None:
    """`start`, `stop`, `pause`, `resume` or `release` for an operator's mission event;
    None for the planner's own decisions."""
    data = event.data or {}
    if event.kind == "decision":
        return "start" if data.get("decision") == "start" and data.get("user") else None
    if event.kind != "operator":
        return None
    if data.get("action"):
        return str(data["action"])
    return "release" if "panic" in event.message else "stop"


def mission_event(sender: Any, instance: Any, created: bool, **kwargs: Any) -> None:
    action = _mission_action(instance) if created else None
    if action is None:
        return
    mission = instance.mission
    audit.record(
        mission.organisation_id,
        audit.Kind.MISSION,
        f"mission.{action}",
        target=mission.name,
        detail={"mission": str(mission.pk), "message": instance.message, **(instance.data or {})},
    )


def envelope_stored(sender: Any, organisation: Any, envelope: dict, **kwargs: Any) -> None:
    audit.record(
        organisation.pk,
        audit.Kind.ENVELOPE,
        "envelope.change",
        target=organisation.name,
        detail={"envelope": envelope},
    )


def refused(
    sender: Any, organisation_id: int, user: Any, action: str, target: str, reason: str, **kw: Any
) -> None:
    """A mission action or envelope change another app refused."""
    audit.record(
        organisation_id,
        action.split(".", 1)[0],
        action,
        target=target,
        outcome="refused",
        actor=user,
        detail={"reason": reason},
    )


def identity_changed(
    sender: Any, organisation_id: int, user: Any, action: str, target: str, changed: dict, **kw: Any
) -> None:
    """An admin set a Remote ID identity: who, when, and the new values."""
    audit.record(
        organisation_id,
        audit.Kind.ORGANISATION,
        action,
        target=target,
        actor=user,
        detail={"changed": changed},
    )


def zone_authorised(sender: Any, instance: Any, created: bool, **kwargs: Any) -> None:
    """An organisation's admin recorded an authorisation to fly in a published zone."""
    if not created:
        return
    audit.record(
        instance.organisation_id,
        audit.Kind.ENVELOPE,
        "zone.authorisation",
        target=f"{instance.zone.identifier} {instance.zone.name}",
        actor=instance.recorded_by,
        detail={
            "zone": instance.zone_id,
            "issued_by": instance.issued_by,
            "reference": instance.reference,
            "expires_at": instance.expires_at.isoformat(),
        },
    )


def connect() -> None:
    """Called once from AppConfig.ready(); senders by label, so no import of their apps."""
    post_save.connect(command_logged, sender="fleet.CommandLog", dispatch_uid="audit-command")
    post_save.connect(mission_event, sender="missions.Event", dispatch_uid="audit-mission")
    post_save.connect(zone_authorised, sender="zones.Authorisation", dispatch_uid="audit-zone")
    envelope_changed.connect(envelope_stored, dispatch_uid="audit-envelope")
    action_refused.connect(refused, dispatch_uid="audit-refused")
    fleet_identity_changed.connect(identity_changed, dispatch_uid="audit-remote-id")
    user_logged_in.connect(signin.signed_in, dispatch_uid="sign-in-record")
    user_login_failed.connect(signin.sign_in_failed, dispatch_uid="sign-in-failed-record")
    post_save.connect(
        passwords.password_saved, sender=settings.AUTH_USER_MODEL, dispatch_uid="password-saved"
    )
    post_save.connect(admin_site.logged, sender="admin.LogEntry", dispatch_uid="audit-admin")
