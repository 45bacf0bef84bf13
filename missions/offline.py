"""A drone that goes offline mid-mission: the mission shows it at once; when the drone is
still offline MISSIONS_OFFLINE_GRACE_S later, its remaining steps are handed over exactly as
for a CRITICAL alarm (missions.replacement). Meanwhile the drone's own fail-safe has brought
it home after its link-loss timeout (onboard.failsafe)."""

from __future__ import annotations

import time

from django.conf import settings
from django.db import transaction

from fleet.models import Drone
from missions.journal import record
from missions.models import Assignment, Event, MissionStatus
from missions.progress import lock_mission


def note_offline(drone_ids: list[str]) -> list[int]:
    """Record on each running mission that its drone went offline and queue the
    replacement after the grace period; the events' ids."""
    from missions import tasks

    flying = Assignment.objects.filter(
        drone__drone_id__in=drone_ids,
        status__in=Assignment.ACTIVE,
        mission__status=MissionStatus.RUNNING,
    ).select_related("mission", "drone")
    grace = settings.MISSIONS_OFFLINE_GRACE_S
    noted = []
    for assignment in flying:
        with transaction.atomic():
            lock_mission(assignment.mission)
            event = _record_offline(assignment, grace)
            kwargs = {
                "mission_id": str(assignment.mission_id),
                "assignment_id": str(assignment.pk),
                "event_id": event.pk,
            }
            transaction.on_commit(
                lambda k=kwargs: tasks.replace_offline.apply_async(kwargs=k, countdown=grace)
            )
        noted.append(event.pk)
    return noted


def _record_offline(assignment: Assignment, grace: float) -> Event:
    drone = assignment.drone
    # The last position heard: where the replacement picks up (as an alarm's position).
    position = None if drone.lat is None else {"lat": drone.lat, "lon": drone.lon, "alt": drone.alt}
    return record(
        assignment.mission,
        Event.Kind.DECISION,
        f"{drone.drone_id} went offline mid-mission; replaced in {grace:g} s unless it is back",
        drone=drone,
        data={
            "decision": "offline",
            "assignment": str(assignment.pk),
            "position": position,
            "received_at": time.time(),
        },
    )


def replace_if_still_offline(mission_id: str, assignment_id: str, event_id: int) -> None:
    """Run the replacement unless the drone came back within the grace period."""
    from missions import replacement

    drone = Drone.objects.filter(assignments__pk=assignment_id).first()
    if drone is None:
        return
    if drone.online:
        assignment = Assignment.objects.select_related("mission").get(pk=assignment_id)
        record(
            assignment.mission,
            Event.Kind.DECISION,
            f"{drone.drone_id} is back online within the grace period: not replaced",
            drone=drone,
            data={"decision": "offline_back", "assignment": assignment_id},
        )
        return
    replacement.replace_drone(
        mission_id=mission_id, assignment_id=assignment_id, alarm_event_id=event_id
    )
