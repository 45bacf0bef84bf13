"""Mission Worker: decode a base64 mission, queue its steps, run them one by one.

The mission arrives as one base64 message; it is decoded (and the decode
timed), its steps go into a FIFO task queue, each step is handed to the component that
executes it, and progress goes back to the ground for every step. The worker runs on its
own thread and never waits for the ground: when the link drops the mission goes on and
progress piles up in the agent's outbox.
"""

from __future__ import annotations

import logging
import math
import queue
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from . import protocol
from .controller import CommandError, Controller
from .fc.base import FlightController, VehicleState
from .navigation import NED, NavigationProcessor, current_ned, inside_cylinder

log = logging.getLogger(__name__)

Publish = Callable[[Any], None]
# Flight seconds between two targets of a paced leg (each is one write to the flight
# controller).
PACE_INTERVAL_S = 0.2
# How far a paced leg's target may be above the drone (PacedLeg): the vertical tolerance a
# waypoint is reached within.
CLIMB_LEASH_M = protocol.DEFAULT_TOLERANCE
# (level, message, sensor, value) → raise an alarm with the current mission context.
RaiseAlarm = Callable[..., None]
EventSink = Callable[[str, dict], None]


class StepFailed(Exception):
    """A step that did not complete; str() is the reason sent in its progress."""


class MissionStopped(Exception):
    """Raised inside a waiting step when the mission is stopped."""


class StepPaused(Exception):
    """Raised inside a waiting step when the mission is paused: the step is flown again,
    from its start, on resume."""


@dataclass
class RunningMission:
    payload: protocol.MissionPayload
    request_id: str | None
    decode_ms: float
    steps: queue.Queue = field(default_factory=queue.Queue)
    index: int | None = None
    stop: threading.Event = field(default_factory=threading.Event)
    stop_reason: str | None = None
    # Set while the operator has the mission paused; `wake` interrupts any wait at a stop,
    # a pause or a resume.
    paused: threading.Event = field(default_factory=threading.Event)
    wake: threading.Event = field(default_factory=threading.Event)
    # The step a pause interrupted, flown again on resume without a second "started".
    retry: protocol.Step | None = None
    # Where the drone was going when it was paused, flown to again on resume.
    saved_target: Any = None
    # When each step was first started (monotonic), so a re-flown step is announced once.
    started: dict[int, float] = field(default_factory=dict)
    # The paced leg being flown (a navigate step with a speed), and whether the mission
    # has the drone facing a region of interest, undone when it ends.
    leg: PacedLeg | None = None
    roi_set: bool = False


@dataclass
class PacedLeg:
    """A leg flown at a set speed: the agent moves the target along the straight line
    from `start` to `end` at `speed` (m/s, flight time), so any flight controller flies
    it at that pace. The envelope checked the leg's end; every point fed lies on the leg.

    The target never runs more than CLIMB_LEASH_M above the drone: while the drone is
    lower than that (its climb slower than the leg's, a late link, a stalled agent whose
    next target would jump ahead), the target waits for it, so the drone climbs before it
    goes on and never meets a rising slope under its path; the time waited is not made
    up by a jump afterwards."""

    start: NED
    end: NED
    speed: float
    flown_s: float = 0.0  # flight seconds of progress along the leg

    @property
    def length(self) -> float:
        return math.dist(self.start, self.end)

    def _at(self, share: float) -> NED:
        return tuple(a + (b - a) * share for a, b in zip(self.start, self.end, strict=True))  # type: ignore[return-value]

    def _share(self) -> float:
        length = self.length
        return 1.0 if length <= 0 else min(1.0, self.flown_s * self.speed / length)

    def advance(self, flight_seconds: float, here: NED | None = None) -> NED:
        """Where the target is after another `flight_seconds` of the leg, held back to
        CLIMB_LEASH_M above the drone at `here` when given."""
        before = self._share()
        self.flown_s += flight_seconds
        share = self._share()
        if here is not None and here[2] - self._at(share)[2] > CLIMB_LEASH_M:
            rise = self.end[2] - self.start[2]
            reach = (here[2] - CLIMB_LEASH_M - self.start[2]) / rise if rise < 0 else before
            share = max(before, min(share, reach))
            self.flown_s = share * self.length / self.speed
        return self.end if share >= 1.0 else self._at(share)

    @property
    def done(self) -> bool:
        return self.flown_s * self.speed >= self.length


def unsupported_step(payload: protocol.MissionPayload, fc: FlightController) -> str | None:
    """Why this drone cannot fly the mission (a step asks for what its flight controller
    cannot do), or None. Checked when the mission arrives, so it is refused whole."""
    for step in payload.steps:
        if step.command == "navigate" and "roi" in step.params and not hasattr(fc, "point_at"):
            protocol_name = getattr(fc, "protocol", "this")
            return (
                f"Step {step.index} (navigate) asks the drone to face a region of interest, "
                f"which the {protocol_name} flight controller driver cannot do."
            )
    return None


def position_of(state: VehicleState) -> protocol.Position | None:
    if state.lat is None or state.lon is None:
        return None
    return protocol.Position(state.lat, state.lon, state.alt or 0.0)


def decode_mission(start: protocol.MissionStart) -> tuple[protocol.MissionPayload, float]:
    """Decode and check a start message's payload; return it and the decode time in ms."""
    began = time.perf_counter()
    payload = protocol.decode_mission_payload(start.payload)
    decode_ms = (time.perf_counter() - began) * 1000.0
    if payload.mission_id != start.mission_id:
        raise protocol.ProtocolError(
            "payload.mission_id",
            f"{payload.mission_id!r} does not match the message's {start.mission_id!r}",
        )
    if payload.assignment_id != start.assignment_id:
        raise protocol.ProtocolError(
            "payload.assignment_id",
            f"{payload.assignment_id!r} does not match the message's {start.assignment_id!r}",
        )
    return payload, decode_ms


def queue_steps(payload: protocol.MissionPayload) -> queue.Queue:
    """The FIFO task queue of the mission's steps, filled in mission order."""
    steps: queue.Queue = queue.Queue()
    for step in payload.steps:
        steps.put_nowait(step)
    return steps


class MissionWorker:
    def __init__(
        self,
        fc: FlightController,
        controller: Controller,
        navigation: NavigationProcessor,
        publish: Publish,
        *,
        raise_alarm: RaiseAlarm | None = None,
        gear: Any = None,
        on_reading: Callable[[str, dict], None] | None = None,
        time_scale: float = 1.0,
        poll_interval: float = 0.05,
        flight_timeout: float = 600.0,
        events: EventSink | None = None,
    ) -> None:
        self.fc = fc
        self.controller = controller
        self.navigation = navigation
        self.publish = publish
        self.raise_alarm = raise_alarm or (lambda *args, **kwargs: None)
        self.gear = gear
        self.on_reading = on_reading or (lambda sensor, reading: None)
        self.time_scale = time_scale
        self.poll_interval = poll_interval
        # In flight seconds: a wait_for_flight that takes longer than this fails.
        self.flight_timeout = flight_timeout
        self.events = events or (lambda kind, details: None)
        # Called with "completed" or "stopped" once a mission has ended (the fail-safe
        # decides what the drone does next).
        self.on_end: Callable[[str], None] = lambda status: None
        self._lock = threading.Lock()
        self._mission: RunningMission | None = None
        self._wake = threading.Event()
        self._closing = threading.Event()
        self._thread: threading.Thread | None = None

    # -- lifecycle ------------------------------------------------------------------------

    def start(self) -> None:
        self._thread = threading.Thread(target=self._run, name="mission-worker", daemon=True)
        self._thread.start()

    def close(self, timeout: float = 5.0) -> None:
        self.stop_current("the agent is shutting down")
        self._closing.set()
        self._wake.set()
        if self._thread is not None:
            self._thread.join(timeout)

    @property
    def current(self) -> protocol.MissionRef | None:
        """The executing mission and step, for heartbeats and alarms."""
        with self._lock:
            mission = self._mission
        if mission is None:
            return None
        return protocol.MissionRef(
            mission.payload.mission_id, mission.payload.assignment_id, mission.index
        )

    @property
    def busy(self) -> bool:
        with self._lock:
            return self._mission is not None

    # -- requests from the ground ---------------------------------------------------------

    def submit(
        self, request: protocol.MissionStart | protocol.MissionStop | protocol.MissionPause
    ) -> None:
        """Handle a parsed `<id>/mission/in` message (called from the MQTT thread)."""
        if isinstance(request, protocol.MissionStop):
            self._handle_stop(request)
        elif isinstance(request, protocol.MissionPause):
            self._handle_pause(request)
        else:
            self._handle_start(request)

    def _handle_pause(self, request: protocol.MissionPause) -> None:
        """Pause or resume the running mission; the worker thread holds and re-flies."""
        with self._lock:
            running = self._mission
        pausing = request.action == "pause"
        if running is None or running.payload.mission_id != request.mission_id:
            error = "The mission is not running on this drone."
        elif running.stop.is_set():
            error = "The mission is stopping."
        elif running.paused.is_set() == pausing:
            error = f"The mission is {'already' if pausing else 'not'} paused."
        else:
            error = None
        if error is not None:
            self._mission_status(protocol.mission_reply(request, "rejected", error=error))
            return
        if pausing:
            running.paused.set()
        else:
            running.paused.clear()
        running.wake.set()
        status = "paused" if pausing else "resumed"
        self.events("mission", {"event": status, "mission_id": request.mission_id})
        self._mission_status(protocol.mission_reply(request, status))

    def _handle_start(self, start: protocol.MissionStart) -> None:
        try:
            payload, decode_ms = decode_mission(start)
        except protocol.ProtocolError as exc:
            self._mission_status(protocol.mission_reply(start, "rejected", error=str(exc)))
            return
        refusal = unsupported_step(payload, self.fc)
        if refusal is not None:
            self._mission_status(protocol.mission_reply(start, "rejected", error=refusal))
            return
        self.events(
            "mission",
            {
                "event": "decoded",
                "mission_id": payload.mission_id,
                "steps": len(payload.steps),
                "decode_ms": decode_ms,
            },
        )
        with self._lock:
            running = self._mission
            if running is None:
                self._mission = RunningMission(
                    payload, start.request_id, decode_ms, queue_steps(payload)
                )
        if running is not None:
            busy = f"Mission {running.payload.mission_id} is still running; stop it first."
            self._mission_status(protocol.mission_reply(start, "rejected", error=busy))
            return
        self._mission_status(protocol.mission_reply(start, "accepted", decode_ms=decode_ms))
        self._wake.set()

    def _handle_stop(self, stop: protocol.MissionStop) -> None:
        with self._lock:
            running = self._mission
        if running is None or running.payload.mission_id != stop.mission_id:
            not_running = "The mission is not running on this drone."
            self._mission_status(protocol.mission_reply(stop, "stopped", error=not_running))
            return
        self.stop_current("stopped by the ground", request_id=stop.request_id)

    def pause_current(self) -> str | None:
        """Pause the running mission (an operator's hold); its id, or None if none runs."""
        with self._lock:
            mission = self._mission
        if mission is None or mission.stop.is_set():
            return None
        payload = mission.payload
        if not mission.paused.is_set():
            mission.paused.set()
            mission.wake.set()
            self.events("mission", {"event": "paused", "mission_id": payload.mission_id})
            self.publish(
                protocol.MissionProgress(payload.mission_id, payload.assignment_id, "paused")
            )
        return payload.mission_id

    def stop_current(self, reason: str, *, request_id: str | None = None) -> bool:
        """Stop the running mission (from the ground or the fail-safe); False if none."""
        with self._lock:
            mission = self._mission
        if mission is None:
            return False
        mission.stop_reason = reason
        if request_id is not None:
            mission.request_id = request_id
        mission.stop.set()
        mission.wake.set()
        return True

    # -- the worker thread ----------------------------------------------------------------

    def _run(self) -> None:
        while not self._closing.is_set():
            self._wake.wait(0.5)
            self._wake.clear()
            with self._lock:
                mission = self._mission
            if mission is None:
                continue
            try:
                self._execute(mission)
            except Exception:  # never let one mission kill the worker
                log.exception("mission %s crashed", mission.payload.mission_id)
                mission.stop_reason = mission.stop_reason or "the mission worker failed"
                self._finish(mission, "stopped", mission.stop_reason)
            finally:
                with self._lock:
                    if self._mission is mission:
                        self._mission = None

    def _execute(self, mission: RunningMission) -> None:
        while True:
            if mission.paused.is_set():
                self._hold_while_paused(mission)
            if mission.stop.is_set():
                self._close_retry(mission)
                self._finish(mission, "stopped", mission.stop_reason)
                return
            step, mission.retry = mission.retry, None
            if step is None:
                try:
                    step = mission.steps.get_nowait()
                except queue.Empty:
                    self._finish(mission, "completed", None)
                    return
            mission.index = step.index
            ok, error = self._run_step(mission, step)
            if not ok and error is None:  # paused part-way: flown again on resume
                mission.retry = step
                continue
            if not ok:
                self._end_on_failure(mission, step, error)
                return

    def _end_on_failure(
        self, mission: RunningMission, step: protocol.Step, error: str | None
    ) -> None:
        """A failed step ends the mission as stopped: with the operator's reason when a
        stop caused it, else naming the step; the mission's end behaviour follows."""
        if mission.stop.is_set():
            self._finish(mission, "stopped", mission.stop_reason)
        else:
            self._finish(mission, "stopped", protocol.step_failure(step.index, step.command, error))

    def _close_retry(self, mission: RunningMission) -> None:
        """A step a pause interrupted, then a stop ended, is reported failed like any
        step a stop interrupts."""
        step, mission.retry = mission.retry, None
        if step is not None:
            started = mission.started[step.index]
            self._record_step(mission, step, "failed", started, {}, "the mission was stopped")

    def _hold_while_paused(self, mission: RunningMission) -> None:
        """Hold where the drone is until resumed (or stopped), then head for the target it
        had when paused. A drone still on the ground is left as it is."""
        state = self.fc.state
        here = current_ned(state)
        mission.saved_target = None
        if state.airborne and here is not None:
            mission.saved_target = self.navigation.last_target
            self.navigation.hold_at(here)
        while mission.paused.is_set() and not mission.stop.is_set():
            mission.wake.wait(0.5)
            mission.wake.clear()
        saved, mission.saved_target = mission.saved_target, None
        if saved is None or mission.stop.is_set():
            return
        if saved.kind == "land":
            self.navigation.execute("land", {})
        else:
            self.navigation.hold_at(saved.ned)

    def _wait(self, mission: RunningMission, seconds: float) -> None:
        """Wait `seconds` (wall), or raise at once when the mission is stopped or paused."""
        deadline = time.monotonic() + seconds
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                return
            if mission.wake.wait(left):
                mission.wake.clear()  # before the checks: a later pause sets it again
            if mission.stop.is_set():
                raise MissionStopped()
            if mission.paused.is_set():
                raise StepPaused()

    def _finish(self, mission: RunningMission, status: str, error: str | None) -> None:
        payload = mission.payload
        # Drain what is left so a stopped mission never runs another step.
        while not mission.steps.empty():
            mission.steps.get_nowait()
        if mission.roi_set:
            try:
                self.fc.point_at(None)  # type: ignore[attr-defined]
            except Exception:
                log.exception("the region of interest of %s was not cleared", payload.mission_id)
            mission.roi_set = False
        mission.leg = None
        self.events("mission", {"event": status, "mission_id": payload.mission_id, "error": error})
        # What the drone does next (hold, return, land) is in place before the ground hears
        # the mission ended: an operator's command sent on that news is not overridden.
        try:
            self.on_end(status)
        except Exception:
            log.exception("the end of mission %s was not handled", payload.mission_id)
        self._mission_status(
            protocol.MissionProgress(
                payload.mission_id,
                payload.assignment_id,
                status,
                error=error,
                request_id=mission.request_id if status == "stopped" else None,
            )
        )

    def _run_step(self, mission: RunningMission, step: protocol.Step) -> tuple[bool, str | None]:
        """(True, None) done, (False, why) failed, (False, None) paused part-way."""
        if step.index not in mission.started:  # a step flown again is reported once
            mission.started[step.index] = time.monotonic()
            self._announce(mission, step)
        started = mission.started[step.index]  # only the step is timed, pauses included
        try:
            result = self._dispatch(mission, step)
        except StepPaused:
            return False, None
        except (StepFailed, CommandError, MissionStopped) as exc:
            error = str(exc) if not isinstance(exc, MissionStopped) else "the mission was stopped"
            self._record_step(mission, step, "failed", started, {}, error)
            return False, error
        except Exception as exc:
            log.exception("step %s failed", step.index)
            error = f"{step.command} failed unexpectedly: {exc}"
            self._record_step(mission, step, "failed", started, {}, error)
            return False, error
        self._record_step(mission, step, "completed", started, result, None)
        return True, None

    def _announce(self, mission: RunningMission, step: protocol.Step) -> None:
        self._step_status(mission, step, "started")
        self.events(
            "step",
            {
                "event": "started",
                "mission_id": mission.payload.mission_id,
                "index": step.index,
                "command": step.command,
                "position": position_of(self.fc.state),
            },
        )

    def _record_step(
        self,
        mission: RunningMission,
        step: protocol.Step,
        status: str,
        started: float,
        result: dict,
        error: str | None,
    ) -> None:
        duration = (time.monotonic() - started) * self.time_scale
        position = position_of(self.fc.state)
        self._step_status(
            mission,
            step,
            status,
            duration_s=duration,
            result=result,
            error=error,
            position=position,
        )
        self.events(
            "step",
            {
                "event": status,
                "mission_id": mission.payload.mission_id,
                "index": step.index,
                "command": step.command,
                "position": position,
                "duration_s": duration,
                "error": error,
            },
        )

    def _dispatch(self, mission: RunningMission, step: protocol.Step) -> dict:
        context = {
            "mission_id": mission.payload.mission_id,
            "assignment_id": mission.payload.assignment_id,
            "index": step.index,
        }
        if step.command == "wait_for_flight":
            return self._wait_for_flight(mission, **step.params, context=context)
        if step.command == "sleep":
            self._wait(mission, step.params["value"] / self.time_scale)
            return {}
        if step.command == "virtualalarm":
            self.raise_alarm(
                step.params["level"], step.params["message"] or "virtual alarm", context=context
            )
            return {"level": step.params["level"]}
        if step.command == "sense":
            return self._sense(step.params["sensor"], context)
        if step.command == "navigate":
            return self._navigate(mission, step.params, context)
        return self.controller.execute(step.command, step.params, context=context)

    def _navigate(self, mission: RunningMission, params: dict, context: dict) -> dict:
        """A mission leg: face its region of interest (or stop facing one), then fly to
        the target, paced at the leg's speed when it has one."""
        roi = params.get("roi")
        if roi is not None or mission.roi_set:
            self.fc.point_at(tuple(roi) if roi is not None else None)  # type: ignore[attr-defined]
            mission.roi_set = roi is not None
        start = self.navigation.last_target
        here = start.ned if start is not None else current_ned(self.fc.state)
        move = {k: v for k, v in params.items() if k not in ("speed", "roi")}
        result = self.controller.execute("navigate", move, context=context)
        mission.leg = None
        speed = params.get("speed")
        if speed is not None and here is not None:
            end = self.navigation.last_target
            assert end is not None
            mission.leg = PacedLeg(here, end.ned, speed)
            self.navigation.hold_at(here)
        return result

    def _sense(self, sensor: str, context: dict) -> dict:
        if self.gear is None:
            raise StepFailed("This drone has no gear manager, so no sensors.")
        try:
            reading = self.gear.read(sensor, self.fc.state)
        except Exception as exc:
            raise StepFailed(str(exc)) from exc
        self.on_reading(sensor, dict(reading, **context))
        return {"sensor": sensor, "reading": reading}

    def _wait_for_flight(
        self,
        mission: RunningMission,
        *,
        horizontal_tolerance: float,
        vertical_tolerance: float,
        photo_distance: float | None = None,
        context: dict | None = None,
    ) -> dict:
        leg = mission.leg
        target = self.navigation.last_target
        if target is None:
            raise StepFailed("No position has been requested yet, so there is nothing to reach.")
        goal = leg.end if leg is not None else target.ned
        camera = _DistanceCamera(photo_distance, current_ned(self.fc.state))
        deadline = time.monotonic() + self.flight_timeout / self.time_scale
        last = time.monotonic()
        pace = max(self.poll_interval, PACE_INTERVAL_S / self.time_scale)
        while True:
            state = self.fc.state
            actual = current_ned(state)
            now = time.monotonic()
            if leg is not None and not leg.done and now - last >= pace:
                self.navigation.hold_at(leg.advance((now - last) * self.time_scale, actual))
                last = now
            if camera.due(actual):
                self.controller.execute("takepic", {}, context=context)
            # A landing is reached on the ground, not 2 m above it: the next step is
            # usually disarm, which is refused while airborne.
            landed = target.kind != "land" or not state.airborne
            if (
                actual is not None
                and landed
                and (leg is None or leg.done)
                and inside_cylinder(
                    actual,
                    goal,
                    horizontal_tolerance=horizontal_tolerance,
                    vertical_tolerance=vertical_tolerance,
                )
            ):
                mission.leg = None
                result = {"target": dict(zip(("north", "east", "down"), goal, strict=True))}
                return result | ({"pictures": camera.taken} if photo_distance else {})
            if now > deadline:
                raise StepFailed(
                    f"The drone did not reach the target within {self.flight_timeout:g} s."
                )
            self._wait(mission, self.poll_interval)

    # -- progress messages ----------------------------------------------------------------

    def _mission_status(self, progress: protocol.MissionProgress) -> None:
        if progress.status in ("accepted", "rejected"):  # _finish logs completed and stopped
            self.events(
                "mission",
                {
                    "event": progress.status,
                    "mission_id": progress.mission_id,
                    "decode_ms": progress.decode_ms,
                },
            )
        self.publish(progress)

    def _step_status(
        self,
        mission: RunningMission,
        step: protocol.Step,
        status: str,
        *,
        duration_s: float | None = None,
        result: dict | None = None,
        error: str | None = None,
        position: protocol.Position | None = None,
    ) -> None:
        if position is None:
            position = position_of(self.fc.state)
        self.publish(
            protocol.step_progress(
                mission.payload,
                step,
                status,
                position,
                duration_s=duration_s,
                result=result,
                error=error,
            )
        )


class _DistanceCamera:
    """Pictures every `distance` metres flown (None: never), the first `distance` from
    where the wait began. Positions arrive in steps (about 1 Hz over UAVTalk): each next
    spot is counted from where the last picture was due, not where it was taken, so a late
    position does not push every later picture back."""

    def __init__(self, distance: float | None, start: NED | None) -> None:
        self.distance = distance
        self.last = start
        self.taken = 0

    def due(self, here: NED | None) -> bool:
        if self.distance is None or here is None:
            return False
        if self.last is None:
            self.last = here
            return False
        gap = math.dist(self.last[:2], here[:2])
        if gap < self.distance:
            return False
        share = self.distance / gap
        self.last = tuple(a + (b - a) * share for a, b in zip(self.last, here, strict=True))  # type: ignore[assignment]
        self.taken += 1
        return True
