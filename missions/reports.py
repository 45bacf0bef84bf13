"""The gateway's handlers for `mission`, `alarms` and `pictures` (workers.dispatch).

Each is `handler(drone_id, parsed_message) -> None | reason dropped`; the drone id is
the topic's, tied to the drone's broker credentials by the ACL. A message the database
refuses (what validation let through) is dropped as `db_rejected`, counted against its
drone, rather than raised.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any

from django.db import DatabaseError, InterfaceError, OperationalError

from fleet.models import Drone
from missions.alarms import apply_alarm
from missions.pictures import store_picture
from missions.progress import apply_progress
from onboard import protocol

log = logging.getLogger(__name__)


def _drone(drone_id: str) -> Drone | None:
    return Drone.objects.filter(drone_id=drone_id).first()


def _apply(drone_id: str, apply: Callable[[Drone, Any], str | None], message: Any) -> str | None:
    drone = _drone(drone_id)
    if drone is None:
        return "unknown_drone"
    try:
        return apply(drone, message)
    except (OperationalError, InterfaceError):
        raise  # the database is away: the gateway retries
    except (DatabaseError, UnicodeEncodeError) as exc:
        log.error("%s from %s refused by the database: %s", type(message).__name__, drone_id, exc)
        return "db_rejected"


def handle_mission(
    drone_id: str, message: protocol.MissionProgress | protocol.StepProgress
) -> str | None:
    return _apply(drone_id, apply_progress, message)


def handle_alarm(drone_id: str, message: protocol.Alarm) -> str | None:
    return _apply(drone_id, apply_alarm, message)


def handle_picture(drone_id: str, message: protocol.Picture) -> str | None:
    return _apply(drone_id, store_picture, message)
