"""Signal receivers: what other apps do, seen from the accounts app without them
importing it (the fleet and missions apps know nothing of accounts)."""

from __future__ import annotations

from typing import Any

from django.conf import settings
from django.contrib.auth.signals import user_logged_in, user_login_failed
from django.db.models.signals import post_delete, post_save

from batteries.signals import changed as battery_changed
from checklists.signals import definition_changed as checklist_definition_changed
from fleet.signals import action_refused, drone_setting_changed, envelope_changed
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
    """An admin set a Remote ID identity, or an operator a drone's setting (its log
    collection): who, when, and the new values."""
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


def checklist_run(sender: Any, instance: Any, created: bool, **kwargs: Any) -> None:
    """A pre-flight checklist was run: its answers and automatic values, and the outcome."""
    if not created:
        return
    audit.record(
        instance.organisation_id,
        audit.Kind.COMMAND,
        "checklist.run",
        target=instance.drone.drone_id,
        outcome="ok" if instance.passed else "failed",
        actor=instance.run_by,
        detail={
            "run": instance.pk,
            "template": instance.template_name,
            "results": instance.results,
            "failures": instance.failures,
            "expires_at": instance.expires_at.isoformat(),
        },
    )


def checklist_defined(
    sender: Any, organisation_id: int, user: Any, action: str, target: str, detail: dict, **kw: Any
) -> None:
    """An admin created, changed or retired a checklist template, or set the rule."""
    audit.record(
        organisation_id, audit.Kind.ORGANISATION, action, target=target, actor=user, detail=detail
    )


def maintenance_signed_off(sender: Any, instance: Any, created: bool, **kwargs: Any) -> None:
    """A maintenance task signed off for a drone: who, the task, notes and parts."""
    if not created:
        return
    audit.record(
        instance.organisation_id,
        audit.Kind.MAINTENANCE,
        "maintenance.sign_off",
        target=f"{instance.drone_ident} {instance.item_name}",
        actor=instance.signed_by,
        detail={
            "entry": instance.pk,
            "schedule": instance.schedule_id,
            "bulletin": instance.bulletin_id,
            "notes": instance.notes,
            "parts": instance.parts,
            "usage": instance.usage,
        },
    )


def _schedule_detail(schedule: Any) -> dict:
    return {
        "schedule": schedule.pk,
        "drone": schedule.drone.drone_id if schedule.drone_id else None,
        "model": schedule.model,
        "every_hours": schedule.every_hours,
        "every_flights": schedule.every_flights,
        "every_days": schedule.every_days,
    }


def maintenance_schedule_saved(sender: Any, instance: Any, created: bool, **kwargs: Any) -> None:
    audit.record(
        instance.organisation_id,
        audit.Kind.MAINTENANCE,
        "maintenance.schedule_" + ("add" if created else "change"),
        target=instance.name,
        detail=_schedule_detail(instance),
    )


def maintenance_schedule_deleted(sender: Any, instance: Any, **kwargs: Any) -> None:
    audit.record(
        instance.organisation_id,
        audit.Kind.MAINTENANCE,
        "maintenance.schedule_remove",
        target=instance.name,
        detail=_schedule_detail(instance),
    )


def maintenance_bulletin_issued(sender: Any, instance: Any, created: bool, **kwargs: Any) -> None:
    if created:
        audit.record(
            instance.organisation_id,
            audit.Kind.MAINTENANCE,
            "maintenance.bulletin",
            target=f"{instance.model or instance.drone.drone_id} {instance.title}",
            actor=instance.issued_by,
            detail={
                "bulletin": instance.pk,
                "model": instance.model,
                "drone": instance.drone.drone_id if instance.drone_id else None,
                "source": instance.source,
                "text": instance.text,
            },
        )


def battery_change(
    sender: Any, organisation_id: int, user: Any, action: str, target: str, changed: dict, **kw: Any
) -> None:
    """A member changed the battery retirement rules (organisation settings), named or
    re-rated a pack, or chose the pack a drone carries: who, and each field's old and new."""
    kind = audit.Kind.ORGANISATION if action == "battery.rules" else audit.Kind.MAINTENANCE
    audit.record(
        organisation_id, kind, action, target=target, actor=user, detail={"changed": changed}
    )


def _connect_maintenance() -> None:
    post_save.connect(
        maintenance_signed_off, sender="maintenance.LogEntry", dispatch_uid="audit-maint-log"
    )
    post_save.connect(
        maintenance_schedule_saved, sender="maintenance.Schedule", dispatch_uid="audit-maint-sch"
    )
    post_delete.connect(
        maintenance_schedule_deleted, sender="maintenance.Schedule", dispatch_uid="audit-maint-del"
    )
    post_save.connect(
        maintenance_bulletin_issued, sender="maintenance.Bulletin", dispatch_uid="audit-maint-bul"
    )
    battery_changed.connect(battery_change, dispatch_uid="audit-battery")


def connect() -> None:
    """Called once from AppConfig.ready(); senders by label, so no import of their apps."""
    post_save.connect(command_logged, sender="fleet.CommandLog", dispatch_uid="audit-command")
    post_save.connect(mission_event, sender="missions.Event", dispatch_uid="audit-mission")
    post_save.connect(zone_authorised, sender="zones.Authorisation", dispatch_uid="audit-zone")
    envelope_changed.connect(envelope_stored, dispatch_uid="audit-envelope")
    action_refused.connect(refused, dispatch_uid="audit-refused")
    fleet_identity_changed.connect(identity_changed, dispatch_uid="audit-remote-id")
    drone_setting_changed.connect(identity_changed, dispatch_uid="audit-drone-setting")
    _connect_maintenance()
    post_save.connect(checklist_run, sender="checklists.Run", dispatch_uid="audit-checklist-run")
    checklist_definition_changed.connect(checklist_defined, dispatch_uid="audit-checklist")
    user_logged_in.connect(signin.signed_in, dispatch_uid="sign-in-record")
    user_login_failed.connect(signin.sign_in_failed, dispatch_uid="sign-in-failed-record")
    post_save.connect(
        passwords.password_saved, sender=settings.AUTH_USER_MODEL, dispatch_uid="password-saved"
    )
    post_save.connect(admin_site.logged, sender="admin.LogEntry", dispatch_uid="audit-admin")
