"""The gateway's handlers for `mission`, `alarms` and `pictures` (workers.dispatch).

Each is `handler(drone_id, parsed_message) -> None | reason dropped`; the drone id is
the topic's, tied to the drone's broker credentials by the ACL.
"""

from __future__ import annotations

from fleet.models import Drone
from missions.alarms import apply_alarm
from missions.pictures import store_picture
from missions.services import apply_progress
from onboard import protocol


def _drone(drone_id: str) -> Drone | None:
    return Drone.objects.filter(drone_id=drone_id).first()


def handle_mission(
    drone_id: str, message: protocol.MissionProgress | protocol.StepProgress
) -> str | None:
    drone = _drone(drone_id)
    if drone is None:
        return "unknown_drone"
    return apply_progress(drone, message)


def handle_alarm(drone_id: str, message: protocol.Alarm) -> str | None:
    drone = _drone(drone_id)
    if drone is None:
        return "unknown_drone"
    return apply_alarm(drone, message)


def handle_picture(drone_id: str, message: protocol.Picture) -> str | None:
    drone = _drone(drone_id)
    if drone is None:
        return "unknown_drone"
    return store_picture(drone, message)
