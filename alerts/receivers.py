"""What raises an alert: a CRITICAL alarm, a replacement, a mission that completed or
failed (all recorded as mission events), and a drone the offline sweep found lost."""

from __future__ import annotations

import time

from django.db.models.signals import post_save

from airspace.signals import separation_lost
from fleet.models import Drone
from fleet.signals import drones_went_offline
from logs.events import figure_drifted
from missions.models import Event, Mission, MissionStatus
from missions.signals import critical_alarm_outside_mission

from .models import Alert
from .raising import raise_alert


def connect() -> None:
    post_save.connect(on_mission_event, sender=Event, dispatch_uid="alerts-mission-event")
    drones_went_offline.connect(on_drones_offline, dispatch_uid="alerts-drones-offline")
    critical_alarm_outside_mission.connect(on_lone_alarm, dispatch_uid="alerts-lone-alarm")
    separation_lost.connect(on_separation_lost, dispatch_uid="alerts-separation-lost")
    figure_drifted.connect(on_figure_drifted, dispatch_uid="alerts-figure-drifted")


def on_mission_event(sender, instance: Event, created: bool, **kwargs) -> None:  # type: ignore[no-untyped-def]
    if not created:
        return
    data = instance.data or {}
    if instance.kind == Event.Kind.ALARM and data.get("level") == "CRITICAL":
        _critical_alarm(instance, data)
    elif instance.kind == Event.Kind.HANDOVER and data.get("reason") == "replacement":
        _replacement(instance, data)
    elif instance.kind == Event.Kind.DECISION:
        _mission_end(instance)


def _critical_alarm(event: Event, data: dict) -> None:
    mission = event.mission
    drone_id = event.drone.drone_id if event.drone else ""
    raise_alert(
        mission.organisation,
        Alert.Kind.CRITICAL_ALARM,
        f"CRITICAL alarm from {drone_id or 'a drone'}: {data.get('message') or 'no message'}",
        source=f"event:{event.pk}",
        detail=f"Mission {mission.name}",
        drone_id=drone_id,
        mission_id=mission.pk,
    )


def on_lone_alarm(sender, drone: Drone, alarm, **kwargs) -> None:  # type: ignore[no-untyped-def]
    """A CRITICAL alarm from a drone flying no mission (outside its envelope, say)."""
    if drone.organisation is None:
        return
    raise_alert(
        drone.organisation,
        Alert.Kind.CRITICAL_ALARM,
        f"CRITICAL alarm from {drone.drone_id}: {alarm.message or 'no message'}",
        source=f"alarm:{drone.drone_id}:{alarm.ts}",
        detail="Not in a mission.",
        drone_id=drone.drone_id,
    )


def _replacement(event: Event, data: dict) -> None:
    mission = event.mission
    raise_alert(
        mission.organisation,
        Alert.Kind.REPLACEMENT,
        f"{data.get('from')} replaced by {data.get('to')} in {mission.name}",
        source=f"event:{event.pk}",
        detail=f"{len(data.get('handed_over') or [])} steps handed over",
        drone_id=str(data.get("to") or ""),
        mission_id=mission.pk,
    )


def _mission_end(event: Event) -> None:
    mission = Mission.objects.filter(pk=event.mission_id).select_related("organisation").first()
    if mission is None or mission.status not in (MissionStatus.COMPLETED, MissionStatus.FAILED):
        return
    completed = mission.status == MissionStatus.COMPLETED
    raise_alert(
        mission.organisation,
        Alert.Kind.MISSION_COMPLETED if completed else Alert.Kind.MISSION_FAILED,
        f"Mission {mission.name} {'completed' if completed else 'failed'}",
        source=f"mission-end:{mission.pk}",
        detail=event.message,
        mission_id=mission.pk,
    )


def on_drones_offline(sender, drone_ids, **kwargs) -> None:  # type: ignore[no-untyped-def]
    drones = Drone.objects.filter(drone_id__in=list(drone_ids)).select_related("organisation")
    for drone in drones:
        if drone.organisation is None:
            continue
        seen = drone.last_seen
        raise_alert(
            drone.organisation,
            Alert.Kind.DRONE_LOST,
            f"{drone.drone_id} lost: no heartbeat"
            + (f" since {seen:%H:%M:%S} UTC" if seen else ""),
            source=f"offline:{drone.drone_id}:{seen.isoformat() if seen else 'never'}",
            detail="It was airborne." if drone.airborne else "",
            drone_id=drone.drone_id,
        )


def on_separation_lost(
    sender: object, drone: Drone, other: Drone, in_s: float, action: str, **kwargs: object
) -> None:
    """The live watch held a drone predicted within the separation minima of another."""
    raise_alert(
        drone.organisation,
        Alert.Kind.CRITICAL_ALARM,
        f"Separation: {drone.drone_id} held, {other.drone_id} within the minima in {in_s:g} s",
        source=f"separation:{drone.drone_id}:{other.drone_id}:{int(time.time())}",
        detail=f"{drone.drone_id} was sent a {action}.",
        drone_id=drone.drone_id,
    )


def on_figure_drifted(sender, log, drone: Drone, title: str, detail: str, source: str, **kwargs):  # type: ignore[no-untyped-def]
    """A log's figure drifting from its drone's history or the fleet: a warning, once per
    log, check and basis; answers whether it was new."""
    return raise_alert(
        log.organisation,
        Alert.Kind.LOG_TREND,
        title,
        source=source,
        detail=detail,
        drone_id=drone.drone_id,
    )
