"""Native MAVLink missions: upload the flight part of a mission to the autopilot and follow it.

For links too weak for step-by-step control, the flying steps of a mission (take-off,
navigate, changeN/changeE/altitude, wait_for_flight, sleep, land) are turned into
MISSION_ITEM_INTs, uploaded with the mission protocol (MISSION_COUNT → MISSION_REQUEST_INT
→ MISSION_ITEM_INT … → MISSION_ACK) and flown in AUTO (PX4: AUTO.MISSION) after
MAV_CMD_MISSION_START; MISSION_ITEM_REACHED marks each step completed, so the ground sees
the same step progress as for a step-by-step mission. ArduPilot keeps home in item 0 and
flies from item 1, so its uploads carry a home item first; PX4's start at item 0.
Steps the autopilot cannot do (arm, takepic, sense, virtualalarm, ...) still run in the
agent between native runs, exactly as the ordinary Mission Worker runs them.

Leg settings: a `navigate` with a `speed` becomes a MAV_CMD_DO_CHANGE_SPEED item before its
waypoint and opens a run of its own, so the speed lasts for that leg only (both autopilots
go back to their default speed when they leave the mission). A leg with a region of
interest, or one whose `wait_for_flight` takes pictures by distance, is flown step by step
(the agent points the nose with the driver's `point_at` and takes each picture itself, so
every picture is recorded as on any other drone).

Enable it per drone with the agent's `--native-missions` flag (`install_native_missions`).
"""

from __future__ import annotations

import logging
import queue
import struct
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from . import protocol
from .fc.base import FlightControllerError, VehicleState
from .fc.mavlink import MavlinkFlightController, enum_name, ned_to_lla
from .mission import MissionStopped, MissionWorker, RunningMission, StepFailed
from .navigation import NED, current_ned, lla_to_ned

log = logging.getLogger(__name__)

ITEM_TIMEOUT_S = 1.5  # wall seconds without an answer before resending
UPLOAD_RETRIES = 5
# Commands that become a mission item of their own, and those that ride on the item
# before them (a wait is the autopilot's acceptance radius; a sleep a loiter time).
ITEM_COMMANDS = ("takeoff", "navigate", "changeN", "changeE", "altitude", "land")
FOLLOWER_COMMANDS = ("wait_for_flight", "sleep")


class MissionUploadError(FlightControllerError):
    """The autopilot refused the mission (result named) or stopped answering."""


def float32(value: float) -> float:
    """The value a float field of a MAVLink message carries (single precision)."""
    return struct.unpack("<f", struct.pack("<f", value))[0]


@dataclass(frozen=True)
class MissionItem:
    """One MISSION_ITEM_INT as sent (x/y are degrees × 1e7 in global frames; z and
    params are single precision, so an item compares equal after a round trip)."""

    command: int
    frame: int = mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
    params: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    x: int = 0
    y: int = 0
    z: float = 0.0
    autocontinue: int = 1

    def __post_init__(self) -> None:
        object.__setattr__(self, "z", float32(self.z))
        object.__setattr__(self, "params", tuple(float32(p) for p in self.params))

    @classmethod
    def from_message(cls, msg: Any) -> MissionItem:
        return cls(
            msg.command,
            msg.frame,
            (msg.param1, msg.param2, msg.param3, msg.param4),
            msg.x,
            msg.y,
            float(msg.z),
            msg.autocontinue,
        )


@dataclass
class NativePlan:
    items: list[MissionItem]
    # For each step of the run, the item whose MISSION_ITEM_REACHED completes it.
    completes_at: list[int]
    end: NED
    lands: bool


def plan_native_run(
    steps: list[protocol.Step], start: NED, home: tuple[float, float, float]
) -> NativePlan:
    """Mission items for a run of native steps, starting from the NED target `start`.

    Relative steps add to the last target, as the Navigation Processor does, so the
    autopilot flies the same shape as step-by-step control would.
    """
    items: list[MissionItem] = []
    completes_at: list[int] = []
    north, east, down = start
    lands = False

    def waypoint(command: int, params: tuple = (0.0, 0.0, 0.0, 0.0)) -> MissionItem:
        lat, lon, _ = ned_to_lla(north, east, down, home)
        return MissionItem(command, params=params, x=round(lat * 1e7), y=round(lon * 1e7), z=-down)

    for step in steps:
        command, params = step.command, step.params
        if command == "takeoff":
            # Where it stands: PX4 reads a take-off item's position, ArduCopter ignores it.
            down = -params["altitude"]
            items.append(waypoint(mavlink.MAV_CMD_NAV_TAKEOFF))
        elif command == "changeN":
            north += params["value"]
            items.append(waypoint(mavlink.MAV_CMD_NAV_WAYPOINT))
        elif command == "changeE":
            east += params["value"]
            items.append(waypoint(mavlink.MAV_CMD_NAV_WAYPOINT))
        elif command == "altitude":
            down -= params["value"]
            items.append(waypoint(mavlink.MAV_CMD_NAV_WAYPOINT))
        elif command == "navigate":
            if "roi" in params:
                raise ValueError("a leg with a region of interest is flown step by step")
            if params.get("speed") is not None:
                # param1 1 = ground speed, param2 m/s, param3 -1 = throttle unchanged.
                speed = (1.0, params["speed"], -1.0, 0.0)
                items.append(
                    MissionItem(mavlink.MAV_CMD_DO_CHANGE_SPEED, mavlink.MAV_FRAME_MISSION, speed)
                )
            north, east, _ = lla_to_ned(params["lat"], params["lon"], 0.0, home)
            down -= params.get("altitude_delta", 0.0)
            items.append(waypoint(mavlink.MAV_CMD_NAV_WAYPOINT))
        elif command == "land":
            down = 0.0
            lands = True
            items.append(waypoint(mavlink.MAV_CMD_NAV_LAND))
        elif command == "sleep":
            items.append(waypoint(mavlink.MAV_CMD_NAV_LOITER_TIME, (params["value"], 0, 0, 0)))
        elif command == "wait_for_flight" and params.get("photo_distance") is not None:
            raise ValueError("pictures by distance are taken step by step")
        elif command != "wait_for_flight" or not items:
            raise ValueError(f"{command} cannot be flown as a native MAVLink mission item")
        completes_at.append(len(items) - 1)
    return NativePlan(items, completes_at, (north, east, down), lands)


def flies_natively(step: protocol.Step, following: protocol.Step | None) -> bool:
    """Whether an item command can be a mission item: not a leg facing a region of
    interest, nor one whose wait takes pictures by distance."""
    if step.command not in ITEM_COMMANDS or "roi" in step.params:
        return False
    return not (
        following is not None
        and following.command == "wait_for_flight"
        and following.params.get("photo_distance") is not None
    )


def native_runs(steps: list[protocol.Step]) -> list[tuple[bool, list[protocol.Step]]]:
    """Split steps into (native?, steps) runs: item commands and what follows them. A
    leg with a speed starts a run of its own and no item command joins it after."""
    runs: list[tuple[bool, list[protocol.Step]]] = []
    paced = False  # the last run holds a leg with a speed
    for position, step in enumerate(steps):
        following = steps[position + 1] if position + 1 < len(steps) else None
        follower = step.command in FOLLOWER_COMMANDS and bool(runs) and runs[-1][0]
        native = flies_natively(step, following) or follower
        has_speed = step.command == "navigate" and step.params.get("speed") is not None
        joins = runs and runs[-1][0] and native and (follower or not (paced or has_speed))
        if joins:
            runs[-1][1].append(step)
        else:
            runs.append((native, [step]))
            paced = False
        paced = paced or (native and has_speed)
    return runs


# --- the mission protocol ----------------------------------------------------------------


class MissionUploader:
    """Upload and download missions over a MavlinkFlightController's link.

    Answers to MISSION_REQUEST_INT are sent from the driver's I/O thread the moment a
    request arrives; the caller's thread only watches for silence and resends.
    """

    def __init__(
        self,
        fc: MavlinkFlightController,
        *,
        item_timeout: float = ITEM_TIMEOUT_S,
        retries: int = UPLOAD_RETRIES,
    ) -> None:
        self.fc = fc
        self.item_timeout = item_timeout
        self.retries = retries
        self.stats = {"uploads": 0, "items_sent": 0, "resends": 0, "failures": 0}

    @property
    def first_seq(self) -> int:
        """Where the uploaded items start: ArduPilot keeps home in item 0, PX4 does not."""
        return 0 if self.fc.is_px4 else 1

    def _home_item(self) -> MissionItem:
        # ArduPilot overwrites item 0 with its home; send the home it has, as QGC does.
        lat, lon, alt = self.fc.state.home or (0.0, 0.0, 0.0)
        return MissionItem(
            mavlink.MAV_CMD_NAV_WAYPOINT,
            frame=mavlink.MAV_FRAME_GLOBAL,
            x=round(lat * 1e7),
            y=round(lon * 1e7),
            z=alt,
        )

    def upload(self, items: list[MissionItem]) -> None:
        """MISSION_COUNT, one MISSION_ITEM_INT per request, until MISSION_ACK; raise
        MissionUploadError naming the MAV_MISSION_RESULT on refusal, or on silence.
        On ArduPilot a home item goes first, so `items` start at `first_seq`."""
        fc = self.fc
        if self.first_seq:
            items = [self._home_item(), *items]
        done = threading.Event()
        progress = threading.Event()
        outcome: dict[str, int] = {}
        last_sent: list[Any] = [None]

        def on_message(msg: Any) -> None:
            kind = msg.get_type()
            if kind in ("MISSION_REQUEST_INT", "MISSION_REQUEST"):
                if getattr(msg, "mission_type", 0) != 0 or not 0 <= msg.seq < len(items):
                    return
                self._send_item(items, msg.seq)
                last_sent[0] = msg.seq
                progress.set()
            elif kind == "MISSION_ACK" and getattr(msg, "mission_type", 0) == 0:
                outcome["result"] = msg.type
                done.set()
                progress.set()  # wake the waiting caller now, not an item timeout later

        def resend() -> None:
            # Silence after the count or after an item: send that one again.
            if last_sent[0] is None:
                self._send_count(items)
            else:
                self._send_item(items, last_sent[0])

        fc.add_message_handler(on_message)
        try:
            self._send_count(items)
            self._until_done(done, progress, resend)
        finally:
            fc.remove_message_handler(on_message)
        result = outcome["result"]
        if result != mavlink.MAV_MISSION_ACCEPTED:
            self.stats["failures"] += 1
            raise MissionUploadError(
                f"The autopilot refused the mission: {enum_name('MAV_MISSION_RESULT', result)}"
            )
        self.stats["uploads"] += 1

    def _send_count(self, items: list[MissionItem]) -> None:
        fc = self.fc
        fc.send("mission_count", fc.target_system, fc.target_component, len(items), 0)

    def _send_item(self, items: list[MissionItem], seq: int) -> None:
        fc, item = self.fc, items[seq]
        fc.send(
            "mission_item_int",
            fc.target_system,
            fc.target_component,
            seq,
            item.frame,
            item.command,
            int(seq == 0),
            item.autocontinue,
            *item.params,
            item.x,
            item.y,
            item.z,
            0,
        )
        self.stats["items_sent"] += 1

    def _until_done(
        self, done: threading.Event, progress: threading.Event, resend: Callable[[], None]
    ) -> None:
        """Wait while the autopilot makes progress; resend after each silent `item_timeout`
        and give up after `retries` silences in a row."""
        silent = 0
        while not done.is_set():
            if progress.wait(self.item_timeout):
                progress.clear()
                silent = 0
                continue
            if done.is_set():
                break
            self.fc._require_connected()
            silent += 1
            if silent > self.retries:
                self.stats["failures"] += 1
                raise MissionUploadError(
                    f"The autopilot stopped answering the mission upload "
                    f"({self.retries} resends, {self.item_timeout:g} s each)"
                )
            self.stats["resends"] += 1
            resend()

    def download(self) -> list[MissionItem]:
        """MISSION_REQUEST_LIST, then every item by MISSION_REQUEST_INT (to verify)."""
        fc = self.fc
        inbox: queue.Queue = queue.Queue()

        def on_message(msg: Any) -> None:
            if msg.get_type() in ("MISSION_COUNT", "MISSION_ITEM_INT"):
                inbox.put(msg)

        def wait_for(kind: str, seq: int | None, resend: Any) -> Any:
            for _ in range(self.retries + 1):
                resend()
                deadline = time.monotonic() + self.item_timeout
                while (left := deadline - time.monotonic()) > 0:
                    try:
                        msg = inbox.get(timeout=left)
                    except queue.Empty:
                        break
                    if msg.get_type() == kind and (seq is None or msg.seq == seq):
                        return msg
            raise MissionUploadError(f"The autopilot did not send {kind} while downloading")

        fc.add_message_handler(on_message)
        try:
            count = wait_for(
                "MISSION_COUNT",
                None,
                lambda: fc.send("mission_request_list", fc.target_system, fc.target_component, 0),
            ).count
            items = []
            for seq in range(self.first_seq, count):
                msg = wait_for(
                    "MISSION_ITEM_INT",
                    seq,
                    lambda seq=seq: fc.send(
                        "mission_request_int", fc.target_system, fc.target_component, seq, 0
                    ),
                )
                items.append(MissionItem.from_message(msg))
            fc.send(
                "mission_ack",
                fc.target_system,
                fc.target_component,
                mavlink.MAV_MISSION_ACCEPTED,
                0,
            )
            return items
        finally:
            fc.remove_message_handler(on_message)


@dataclass
class ProgressFollower:
    """Collects MISSION_ITEM_REACHED and MISSION_CURRENT from the driver's I/O thread."""

    reached: queue.Queue = field(default_factory=queue.Queue)
    current: int = -1

    def __call__(self, msg: Any) -> None:
        kind = msg.get_type()
        if kind == "MISSION_ITEM_REACHED":
            self.reached.put(msg.seq)
        elif kind == "MISSION_CURRENT":
            self.current = msg.seq


# --- the worker --------------------------------------------------------------------------


class NativeMissionWorker(MissionWorker):
    """A Mission Worker that flies runs of flying steps as native MAVLink missions."""

    def __init__(self, fc: MavlinkFlightController, *args: Any, **kwargs: Any) -> None:
        super().__init__(fc, *args, **kwargs)
        self.mav_fc = fc
        self.uploader = MissionUploader(fc)

    def _execute(self, mission: RunningMission) -> None:
        steps: list[protocol.Step] = []
        while not mission.steps.empty():
            steps.append(mission.steps.get_nowait())
        for native, run in native_runs(steps):
            if mission.stop.is_set():
                self._finish(mission, "stopped", mission.stop_reason)
                return
            if native:
                ok, failed, error = self._run_native(mission, run)
            else:
                ok, failed, error = True, run[0], None
                for step in run:
                    mission.index = step.index
                    ok, error = self._run_step(mission, step)
                    if not ok:
                        failed = step
                        break
            if not ok:
                self._end_on_failure(mission, failed, error)
                return
        self._finish(mission, "completed", None)

    def _run_native(
        self, mission: RunningMission, run: list[protocol.Step]
    ) -> tuple[bool, protocol.Step, str | None]:
        """Upload the run, fly it in AUTO and report each step as its item is reached."""
        first = run[0]
        mission.index = first.index
        started = time.monotonic()
        self._step_status(mission, first, "started")
        try:
            if mission.roi_set:  # a step-by-step leg before this run faced a ROI
                self.mav_fc.point_at(None)
                mission.roi_set = False
            plan = self._plan(run)
            self.uploader.upload(plan.items)
            follower = ProgressFollower()
            self.mav_fc.add_message_handler(follower)
            try:
                first = self.uploader.first_seq
                self.mav_fc.command_long(
                    mavlink.MAV_CMD_MISSION_START, first, first + len(plan.items) - 1
                )
                self._follow(mission, run, plan, follower, started)
            finally:
                self.mav_fc.remove_message_handler(follower)
        except (StepFailed, FlightControllerError, ValueError, MissionStopped) as exc:
            step = run[mission_position(run, mission.index)]
            error = "the mission was stopped" if isinstance(exc, MissionStopped) else str(exc)
            if isinstance(exc, MissionStopped):
                self._hold()
            self._record_step(mission, step, "failed", started, {}, error)
            return False, step, error
        if not plan.lands:
            # Leave the autopilot holding the run's last point in GUIDED, with the
            # Navigation Processor's target there, as step-by-step flight would.
            self.navigation.hold_at(plan.end)
        return True, run[-1], None

    def _plan(self, run: list[protocol.Step]) -> NativePlan:
        state: VehicleState = self.fc.state
        if not state.armed:
            raise StepFailed(f"The drone is not armed; arm it before {run[0].command}.")
        if state.home is None:
            raise StepFailed("The flight controller has no home position yet.")
        target = self.navigation.last_target
        start = target.ned if target is not None else current_ned(state)
        if start is None:
            raise StepFailed("The drone's position is not known yet (no GPS fix).")
        return plan_native_run(run, start, state.home)

    def _follow(
        self,
        mission: RunningMission,
        run: list[protocol.Step],
        plan: NativePlan,
        follower: ProgressFollower,
        started: float,
    ) -> None:
        position = 0  # next step of the run to complete
        step_started = started
        quiet_limit = self.flight_timeout / self.time_scale
        last_progress = time.monotonic()
        while position < len(run):
            if mission.stop.is_set():
                raise MissionStopped()
            try:
                seq = follower.reached.get(timeout=self.poll_interval)
            except queue.Empty:
                if time.monotonic() - last_progress > quiet_limit:
                    raise StepFailed(
                        f"The autopilot reached no mission item within {self.flight_timeout:g} s."
                    ) from None
                if not self.fc.state.connected:
                    raise StepFailed(
                        "The flight controller link was lost during the native mission."
                    ) from None
                continue
            last_progress = time.monotonic()
            seq -= self.uploader.first_seq  # the autopilot's numbering → the plan's
            while position < len(run) and plan.completes_at[position] <= seq:
                step = run[position]
                self._record_step(
                    mission, step, "completed", step_started, {"native_item": seq}, None
                )
                position += 1
                if position < len(run):
                    mission.index = run[position].index
                    step_started = time.monotonic()
                    self._step_status(mission, run[position], "started")

    def _hold(self) -> None:
        try:
            self.mav_fc.set_mode("GUIDED")
        except FlightControllerError as exc:
            log.warning("could not leave AUTO after a stop: %s", exc)


def mission_position(run: list[protocol.Step], index: int | None) -> int:
    for position, step in enumerate(run):
        if step.index == index:
            return position
    return 0


def install_native_missions(agent: Any) -> NativeMissionWorker:
    """Give an Agent (before `start()`) a Mission Worker that flies natively over MAVLink."""
    if not isinstance(agent.fc, MavlinkFlightController):
        raise ValueError("native missions need the MAVLink flight controller (--fc mavlink)")
    old: MissionWorker = agent.worker
    worker = NativeMissionWorker(
        agent.fc,
        old.controller,
        old.navigation,
        old.publish,
        raise_alarm=old.raise_alarm,
        gear=old.gear,
        on_reading=old.on_reading,
        time_scale=old.time_scale,
        poll_interval=old.poll_interval,
        flight_timeout=old.flight_timeout,
        events=old.events,
    )
    worker.on_end = old.on_end
    agent.worker = worker
    agent.failsafe.stop_mission = worker.stop_current
    return worker
