"""Warnings before a task grounds a drone: one WARNING alert when a schedule's item comes
within MAINTENANCE_DUE_SOON_FRACTION of its interval, and one when it falls due, each once
per counting cycle (a sign-off starts a new one). Heard after every flight is recorded
(flight hours and flights grow then) and swept by the beat (calendar days grow on their
own). Bulletins raise none: an admin issued them."""

from __future__ import annotations

from alerts.models import Alert
from alerts.raising import raise_alert
from fleet.models import Drone

from . import due
from .models import Schedule

TITLES = {due.DUE_SOON: "due soon", due.DUE: "due: the drone may not fly until it is signed off"}


def warn(drone: Drone) -> int:
    """Raise the drone's warnings not raised yet in this cycle; how many were raised."""
    raised = 0
    for item in due.items(drone):
        if item.schedule_id is None or item.status not in TITLES:
            continue
        cycle = f"{drone.pk}:{item.schedule_id}:{item.since.timestamp():.0f}"
        alert = raise_alert(
            drone.organisation,
            Alert.Kind.MAINTENANCE,
            f"{drone.drone_id}: maintenance {item.name!r} {TITLES[item.status]}",
            source=f"maintenance:{item.status}:{cycle}",
            detail="; ".join(m.text for m in item.measures),
            drone_id=drone.drone_id,
        )
        raised += alert is not None
    return raised


def sweep() -> int:
    """Every drone of an organisation that has schedules: the beat's pass for days."""
    organisations = Schedule.objects.values("organisation_id").distinct()
    drones = Drone.objects.filter(organisation_id__in=organisations).select_related("organisation")
    return sum(warn(drone) for drone in drones.iterator(chunk_size=200))
