"""Messages to drones about their missions, through the gateway's Redis outbox
(`workers.outbox`), always after the transaction that recorded them commits, so a progress
report can never arrive for a row that is not there yet."""

from __future__ import annotations

from collections.abc import Iterable

from django.conf import settings
from django.db import transaction

from airspace import landing
from fleet import envelopes
from fleet.models import Drone
from missions.models import (
    Assignment,
    Mission,
    Step,
)
from onboard import protocol
from workers import outbox


def step_dicts(steps: Iterable[Step]) -> list[dict]:
    return [{"index": s.index, "command": s.command, "params": s.params} for s in steps]


def send_assignment(assignment: Assignment) -> None:
    """Publish the assignment's steps (preparation first, then its mission steps)."""
    indexes = list(assignment.preparation) + list(assignment.step_indexes)
    by_index = {
        s.index: s for s in Step.objects.filter(mission_id=assignment.mission_id, index__in=indexes)
    }
    steps = step_dicts(by_index[i] for i in indexes)
    message = protocol.mission_start(str(assignment.mission_id), str(assignment.id), steps)
    # Its issue time: a drone refuses a start queued too long while it was away.
    outbox.send_to_drone(
        assignment.drone.drone_id,
        "mission",
        {**message.to_dict(), "ts": protocol.now()},
        ttl=settings.MISSIONS_START_TTL_S,
    )
    if Mission.objects.filter(pk=assignment.mission_id, held=True).exists():
        # A drone sent to a paused mission (a replacement) holds as the others do.
        pause = protocol.mission_pause(str(assignment.mission_id), "pause").to_dict()
        outbox.send_to_drone(assignment.drone.drone_id, "mission", pause)


def send_stop(drone_id: str, mission_id: str, then: str | None = None) -> None:
    """Stop the drone's mission; `then` (protocol.STOP_FOLLOW_UPS) is what it does next,
    holding where it is when not given."""
    message = protocol.MissionStop(protocol.new_request_id(), str(mission_id)).to_dict()
    if then is not None:
        message["then"] = then
    outbox.send_to_drone(drone_id, "mission", message)


def stop_and_send_home(drone: Drone, mission_id: str) -> None:
    """Stop the drone's mission and send it home through its landing site's queue
    (airspace/landing.py), after the commit: as before (`then` return) when the site is
    free, else stopped where it is, and its hold over home at its layer sent by the
    queue once the stop is behind it (a hold sent with the stop is overridden by the
    stop's own hold). A hold the envelope refuses leaves the queue, and the drone is sent
    home as before."""
    drone_id = drone.drone_id
    queued = landing.send_home(drone)
    if queued is not None:
        command, params = landing.hold_command(drone, queued)
        try:
            envelopes.check_command(drone, command, params, confirmed=True)
        except envelopes.EnvelopeRefusal as exc:
            landing.leave(drone, f"its hold was refused: {exc.message}")
        else:
            landing.hold_after_stop(drone)
            transaction.on_commit(lambda: send_stop(drone_id, mission_id))
            return
    transaction.on_commit(lambda: send_stop(drone_id, mission_id, then="return"))


def send_alarm_ack(drone_id: str, level: str) -> None:
    """Tell the drone its alarm arrived, so it stops repeating it."""
    outbox.send_to_drone(drone_id, "alarms", protocol.AlarmAck(level).to_dict())


def send_control(drone_id: str, command: str, params: dict | None = None) -> None:
    request = protocol.control_request(command, params or {})
    outbox.send_to_drone(drone_id, "control", request.to_dict())
