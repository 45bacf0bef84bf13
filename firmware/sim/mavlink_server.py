"""The simulator's MAVLink personality: an ArduCopter-like (or PX4-like) autopilot, sans-I/O.

`MavlinkSession` has BoardSession's shape (`receive(data, now)`, `tick(now)`,
`take_output()`, `on_reboot`), so `firmware.sim.server.serve` runs it over TCP (like
ArduPilot SITL on 5760) or a pty. Same `Vehicle` kinematics, battery and time scale as the
UAVTalk personality; only the language differs:

- HEARTBEAT at 1 Hz (wall clock: the link is real even when physics run faster), and
  again at once when arming or mode changes;
- streams on request: SET_MESSAGE_INTERVAL (per message) or REQUEST_DATA_STREAM (groups),
  scheduled in simulated time and capped at MAX_WALL_HZ on the wall clock;
- COMMAND_LONG / COMMAND_INT with a COMMAND_ACK each: ARM_DISARM (denied when the battery
  is critical, disarm denied in the air unless forced with 21196), DO_SET_MODE, NAV_TAKEOFF
  (GUIDED, armed), NAV_LAND, NAV_RETURN_TO_LAUNCH, MISSION_START, DO_REPOSITION,
  SET_MESSAGE_INTERVAL, REQUEST_MESSAGE, PREFLIGHT_REBOOT_SHUTDOWN; others UNSUPPORTED;
- SET_POSITION_TARGET_GLOBAL_INT / LOCAL_NED in GUIDED;
- the mission protocol (upload and download, MISSION_ITEM_INT and legacy MISSION_ITEM),
  AUTO mode flying the items, MISSION_CURRENT and MISSION_ITEM_REACHED;
- each autopilot's preconditions, refused with its result and STATUSTEXT: ArduPilot's
  take-off only armed in GUIDED, setpoints only in GUIDED, no arming in AUTO/RTL/LAND, AUTO
  only with a mission (item 0 is home; armed on the ground it must start with a take-off);
- with `autopilot="px4"`: PX4's HEARTBEAT and main/sub modes, default streams without
  requests, NAV_TAKEOFF from any mode to an AMSL altitude (Takeoff mode, then Hold),
  DO_REPOSITION into Hold, OFFBOARD only on a setpoint stream already running (> 2 Hz for
  a second) and left for Hold when it stops for COM_OF_LOSS_T, AUTO.MISSION only with a
  mission (MISSION_START arms);
- both: position modes and arming in them need a GPS fix (SIM_GPS_DISABLE takes it away),
  RTL climbs to RTL_ALT / RTL_RETURN_ALT, flies home, lands and disarms, AUTOPILOT_VERSION
  and EXTENDED_SYS_STATE;
- parameters (PARAM_SET/READ/LIST), including fault knobs in the style of SITL's SIM_*:
  SIM_CMD_MUTE (a command id never answered), SIM_JUNK_RATE (bad-CRC and unknown-id
  frames per second sent to the ground), SIM_MSGINT_OFF (answer SET_MESSAGE_INTERVAL as
  UNSUPPORTED, like old firmware), SIM_LOSS_PCT (ground-to-vehicle messages lost, %),
  BATT_CRT_PCT (critical battery, % left).
"""

from __future__ import annotations

import logging
import math
import random
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from firmware.sim.flight_log import LogServer
from firmware.sim.mavlink_streams import AUTOPILOT_ONLY, STREAMED
from firmware.sim.receiver import ARMED, DISARMED
from firmware.sim.remote_id import RemoteIdModule
from firmware.sim.vehicle import PathTarget, Vehicle, lla_to_ned
from firmware.sim.wind import WindFile, wind_ned
from onboard.fc.mavlink import COPTER_MODES, FORCE_MAGIC, MavlinkCodec

log = logging.getLogger(__name__)

SYSTEM_ID = 1
COMPONENT_ID = mavlink.MAV_COMP_ID_AUTOPILOT1
HEARTBEAT_S = 1.0
MAX_WALL_HZ = 50.0
GCS_TIMEOUT_S = 5.0
UPLOAD_RETRY_S = 0.5  # wall seconds before re-requesting a mission item
UPLOAD_RETRIES = 6
ACCEPTANCE_RADIUS_M = 1.0
BOOT_TIME_S = 2.0
MODE_NAMES = {number: name for name, number in COPTER_MODES.items()}
FLYING_MODES = (
    "GUIDED",
    "AUTO",
    "LOITER",
    "RTL",
    "LAND",
    "BRAKE",
    "POSHOLD",
    "TAKEOFF",
    "OFFBOARD",
)
NOT_ARMABLE = ("AUTO", "RTL", "LAND")
# Modes that need a position estimate (a GPS fix) to be entered, on both autopilots.
POSITION_MODES = ("GUIDED", "AUTO", "LOITER", "RTL", "BRAKE", "POSHOLD", "TAKEOFF", "OFFBOARD")
# The PX4 flavour: internal mode ↔ PX4 (main mode, sub mode) in custom_mode bits 16-23/24-31.
PX4_MODES = {
    "STABILIZE": (1, 0),  # MANUAL
    "TAKEOFF": (4, 2),  # AUTO.TAKEOFF: climbs to MIS_TAKEOFF_ALT, then holds
    "GUIDED": (4, 3),  # AUTO.LOITER, hold: where DO_REPOSITION flies
    "AUTO": (4, 4),  # AUTO.MISSION
    "RTL": (4, 5),
    "LAND": (4, 6),
    "OFFBOARD": (6, 0),  # follows the SET_POSITION_TARGET_* stream
}
PX4_TO_INTERNAL = {pair: name for name, pair in PX4_MODES.items()} | {
    (3, 0): "GUIDED",  # POSCTL holds position like hold does here
}
PX4_MODE_NAMES = {
    "STABILIZE": "Manual",
    "TAKEOFF": "Takeoff",
    "GUIDED": "Hold",
    "AUTO": "Mission",
    "RTL": "Return",
    "LAND": "Land",
    "OFFBOARD": "Offboard",
}
# PX4 leaves OFFBOARD when no setpoint came for COM_OF_LOSS_T, and enters it only on a
# stream faster than 2 Hz that has run for a second (wall clock: the link is real).
OFFBOARD_MAX_GAP_S = 0.5
OFFBOARD_WARMUP_S = 1.0
STREAM_GROUPS = {
    mavlink.MAV_DATA_STREAM_RAW_SENSORS: ("HIGHRES_IMU", "GPS_RAW_INT"),
    mavlink.MAV_DATA_STREAM_EXTENDED_STATUS: ("SYS_STATUS", "BATTERY_STATUS", "MISSION_CURRENT"),
    mavlink.MAV_DATA_STREAM_POSITION: ("GLOBAL_POSITION_INT", "LOCAL_POSITION_NED"),
    mavlink.MAV_DATA_STREAM_EXTRA1: ("ATTITUDE",),
    mavlink.MAV_DATA_STREAM_EXTRA3: ("WIND",),  # ArduPilot's SRx_EXTRA3 carries WIND
}
STREAMABLE = tuple(STREAMED)
STREAM_IDS = {getattr(mavlink, f"MAVLINK_MSG_ID_{name}"): name for name in STREAMABLE}
DEFAULT_PARAMS = {
    "BATT_CRT_PCT": 15.0,
    "DISARM_DELAY": 2.0,
    "SIM_CMD_MUTE": 0.0,
    "SIM_GPS_DISABLE": 0.0,
    "SIM_JUNK_RATE": 0.0,
    "SIM_MSGINT_OFF": 0.0,
    "SIM_LOSS_PCT": 0.0,
    # The wind (firmware/sim/wind.py): m/s, and degrees it comes from, as in ArduPilot SITL.
    "SIM_WIND_SPD": 0.0,
    "SIM_WIND_DIR": 0.0,
}
# Each autopilot's own names for what the simulator models (their documented defaults).
AUTOPILOT_PARAMS = {
    "ardupilot": {"WPNAV_SPEED": 1000.0, "RTL_ALT": 1500.0},  # cm/s, cm
    "px4": {"MIS_TAKEOFF_ALT": 2.5, "RTL_RETURN_ALT": 60.0, "COM_OF_LOSS_T": 1.0},  # m, m, s
}
# Streams PX4 sends on a link without being asked (Hz), as its "normal" MAVLink mode does.
PX4_DEFAULT_RATES = {
    "SYS_STATUS": 1.0,
    "EXTENDED_SYS_STATE": 1.0,
    "GLOBAL_POSITION_INT": 5.0,
    "LOCAL_POSITION_NED": 1.0,
    "ATTITUDE": 10.0,
    "GPS_RAW_INT": 1.0,
    "BATTERY_STATUS": 0.5,
    "HOME_POSITION": 0.5,
    "MISSION_CURRENT": 1.0,
}
NAV_POSITION_ITEMS = (
    mavlink.MAV_CMD_NAV_WAYPOINT,
    mavlink.MAV_CMD_NAV_LOITER_TIME,
    mavlink.MAV_CMD_NAV_LOITER_UNLIM,
    mavlink.MAV_CMD_NAV_TAKEOFF,
    mavlink.MAV_CMD_NAV_LAND,
    mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH,
)


@dataclass
class MissionItem:
    """One stored item; lat/lon in degrees (None for local frames), alt above home."""

    seq: int
    frame: int
    command: int
    params: tuple[float, float, float, float]
    x: float
    y: float
    z: float
    autocontinue: int = 1

    def wire(self) -> dict:
        """The MISSION_ITEM_INT fields, as a ground station uploaded them."""
        if self.frame in (mavlink.MAV_FRAME_LOCAL_NED, mavlink.MAV_FRAME_LOCAL_ENU):
            x, y = round(self.x * 1e4), round(self.y * 1e4)
        else:
            x, y = round(self.x * 1e7), round(self.y * 1e7)
        return {"frame": self.frame, "command": self.command, "x": x, "y": y, "z": self.z}


@dataclass
class SimStats:
    messages_in: int = 0
    commands: int = 0
    acks: int = 0
    muted: int = 0
    lost_in: int = 0
    junk_sent: int = 0
    setpoints: int = 0
    setpoints_ignored: int = 0
    mission_uploads: int = 0
    reboots: int = 0


@dataclass
class _Upload:
    count: int
    items: list[MissionItem] = field(default_factory=list)
    asked_at: float = 0.0
    tries: int = 0
    legacy: bool = False


@dataclass
class MavlinkSession:
    vehicle: Vehicle
    time_scale: float = 1.0
    link_timeout_s: float = GCS_TIMEOUT_S
    autopilot: str = "ardupilot"  # or "px4": PX4's modes, AMSL take-off, DO_REPOSITION
    on_reboot: Callable[[], None] | None = None
    stats: SimStats = field(default_factory=SimStats)
    # A Remote ID module on the bus (`--remote-id`), answering OPEN_DRONE_ID_ARM_STATUS.
    remote_id: RemoteIdModule | None = None
    # The battery's serial number SMART_BATTERY_INFO reports (`--battery-serial`); None:
    # a battery without one, the message is not sent.
    battery_serial: str | None = None

    def __post_init__(self) -> None:
        if self.autopilot not in AUTOPILOT_PARAMS:
            raise ValueError(f"unknown autopilot {self.autopilot!r}")
        self.codec = MavlinkCodec(SYSTEM_ID, COMPONENT_ID)
        self.decoder = self.codec  # the name serve()/__main__ log stats from
        # The Remote ID module speaks as its own component on the vehicle's system.
        self.module_codec = MavlinkCodec(SYSTEM_ID, mavlink.MAV_COMP_ID_ODID_TXRX_1)
        self.params = DEFAULT_PARAMS | AUTOPILOT_PARAMS[self.autopilot]
        self.mode = "STABILIZE"
        self.intervals: dict[str, float] = {}  # message → simulated seconds between sends
        self._default_streams()
        # The setpoint stream (wall clock): when it last arrived and since when unbroken.
        self.setpoint_at = -math.inf
        self.setpoint_stream_since = -math.inf
        self.rtl_phase = "climb"
        self.takeoff_target = (0.0, 0.0, 0.0)  # north, east, altitude above home
        self.next_due: dict[str, float] = {}
        self.last_sent_wall: dict[str, float] = {}
        self.mission: list[MissionItem] = []
        self.current = 0
        self.item_started = False
        self.hold_until: float | None = None
        self.mission_done = False
        self.upload: _Upload | None = None
        self.gcs_heard = -math.inf
        self.gcs: tuple[int, int] = (255, 0)
        self._out = bytearray()
        self._last_real: float | None = None
        self._last_heartbeat = -math.inf
        self._landed_at: float | None = None
        self._booting_until = 0.0
        self._junk_due = 0.0
        self._was_critical = False
        self._send_heartbeat_now = False
        self._reboot_due: float | None = None
        self._rx_now = 0.0
        self._rng = random.Random(1)  # repeatable losses
        # The waypoint speed the vehicle flies at unless a mission item changes it.
        self.cruise_speed = self.vehicle.config.max_horizontal
        # MAV_CMD_DO_SET_CAM_TRIGG_DIST in a mission: metres between shots (0: off), where
        # the last one was taken, and how many were taken.
        self.trigger_distance = 0.0
        self.trigger_at: tuple[float, float] | None = None
        self.camera_triggers = 0
        # The autopilot's own log of each flight, served over the log protocol.
        self.flight_logs = LogServer(self.autopilot)
        # A wind file (`--wind-file`) that sets SIM_WIND_SPD/SIM_WIND_DIR when it changes.
        self.wind_file: WindFile | None = None

    # --- helpers ------------------------------------------------------------------------
    @property
    def armed(self) -> bool:
        return self.vehicle.receiver.state == ARMED

    @property
    def has_position(self) -> bool:
        """A GPS fix, hence a global position estimate (SIM_GPS_DISABLE takes it away)."""
        return not self.params["SIM_GPS_DISABLE"]

    def _default_streams(self) -> None:
        # PX4 streams on every link unasked; ArduPilot waits for SRx_/interval requests.
        if self.autopilot == "px4":
            self.intervals.update({name: 1.0 / hz for name, hz in PX4_DEFAULT_RATES.items()})
        # A Remote ID transponder reports its arm status unasked, once a second.
        if self.remote_id is not None:
            self.intervals["OPEN_DRONE_ID_ARM_STATUS"] = 1.0

    @property
    def booting(self) -> bool:
        return self.vehicle.time < self._booting_until

    def _send(self, name: str, *args: Any, **kwargs: Any) -> None:
        self._out += self.codec.encode(name, *args, **kwargs)

    def take_output(self) -> bytes:
        out = bytes(self._out)
        self._out.clear()
        return out

    def statustext(self, severity: int, text: str) -> None:
        log.info("STATUSTEXT %s", text)
        self._send("statustext", severity, text.encode()[:50])

    def _ack(self, command: int, result: int) -> None:
        self.stats.acks += 1
        self._send("command_ack", command, result, 0, 0, self.gcs[0], self.gcs[1])

    def _set_armed(self, armed: bool) -> None:
        self.vehicle.receiver.state = ARMED if armed else DISARMED
        if armed:
            v = self.vehicle
            v.target = PathTarget("HoldPosition", (v.ned[0], v.ned[1], v.ned[2]))
        self._landed_at = None
        self._sync_vehicle_mode()
        self._send_heartbeat_now = True

    def set_mode(self, mode: str) -> None:
        """Enter a mode unconditionally (the autopilot's own switches, failsafes)."""
        before = self.mode
        self.mode = mode
        v = self.vehicle
        if before != mode:
            self._leave_mode(mode)
        if mode in ("GUIDED", "LOITER", "BRAKE", "POSHOLD", "OFFBOARD") and before != mode:
            v.target = PathTarget("HoldPosition", (v.ned[0], v.ned[1], v.ned[2]))
        elif mode == "LAND":
            v.target = PathTarget("Land", (v.ned[0], v.ned[1], 0.0))
        elif mode == "RTL":
            self._start_rtl()
        elif mode == "AUTO" and before != "AUTO":
            self.item_started = False
            self.mission_done = False
        self._sync_vehicle_mode()
        self._send_heartbeat_now = True

    def _leave_mode(self, mode: str) -> None:
        """What a mode change resets: the mission's speed and camera triggering, and the
        region of interest (ArduCopter re-initialises its yaw in every mode it enters;
        PX4 drops the ROI when it returns or lands)."""
        self.vehicle.config.max_horizontal = self.cruise_speed
        self.trigger_distance = 0.0
        if not self.px4 or mode in ("RTL", "LAND"):
            self.vehicle.roi = None

    def mode_refusal(self, mode: str) -> str | None:
        """Why the autopilot would not enter `mode` now (None: it would), in its words."""
        if mode in POSITION_MODES and not self.has_position:
            if self.px4:
                return f"{PX4_MODE_NAMES.get(mode, mode)} mode not available: no global position"
            return f"Mode change to {mode} failed: requires position"
        if mode == "OFFBOARD" and not self._offboard_signal(self._rx_now):
            return "Offboard mode not available: no setpoint stream (> 2 Hz) yet"
        if mode == "AUTO":
            return self._auto_refusal()
        return None

    def _auto_refusal(self) -> str | None:
        if len(self.mission) <= self.first_seq:
            if self.px4:
                return "Mission mode not available: no valid mission"
            return "Mode change to AUTO failed: no mission"
        first = self.mission[self.first_seq]
        if (
            not self.px4
            and self.armed
            and not self.vehicle.airborne
            and first.command != mavlink.MAV_CMD_NAV_TAKEOFF
        ):
            # ArduCopter's guard against flips: armed on the ground, AUTO must take off.
            return "Auto: Missing Takeoff Cmd"
        return None

    def request_mode(self, mode: str) -> int:
        """A ground station's mode change: the refusal result and STATUSTEXT, or the mode."""
        reason = self.mode_refusal(mode)
        if reason is not None:
            self.statustext(mavlink.MAV_SEVERITY_CRITICAL, reason)
            # PX4 answers a mode it cannot enter now as temporarily rejected, ArduPilot failed.
            return (
                mavlink.MAV_RESULT_TEMPORARILY_REJECTED if self.px4 else mavlink.MAV_RESULT_FAILED
            )
        self.set_mode(mode)
        return mavlink.MAV_RESULT_ACCEPTED

    @property
    def first_seq(self) -> int:
        """The first flyable mission item: ArduPilot keeps home in item 0, PX4 does not."""
        return 0 if self.px4 else 1

    def _rtl_altitude(self) -> float:
        if self.px4:
            return self.params["RTL_RETURN_ALT"]
        return self.params["RTL_ALT"] / 100.0

    def _start_rtl(self) -> None:
        # Both autopilots: climb to the return altitude, fly home at it, land, disarm.
        v = self.vehicle
        if not v.airborne:
            self.rtl_phase = "land"
            v.target = PathTarget("Land", (0.0, 0.0, 0.0))
            return
        self.rtl_phase = "climb"
        down = min(v.ned[2], -self._rtl_altitude())
        v.target = PathTarget("Endpoint", (v.ned[0], v.ned[1], down))

    def _run_rtl(self) -> None:
        v = self.vehicle
        if self.mode != "RTL" or not self.armed or self.rtl_phase == "land":
            return
        if math.dist(v.ned, v.target.end) >= ACCEPTANCE_RADIUS_M:
            return
        if self.rtl_phase == "climb":
            self.rtl_phase = "return"
            v.target = PathTarget("Endpoint", (0.0, 0.0, v.target.end[2]))
        else:
            self.rtl_phase = "land"
            v.target = PathTarget("Land", (0.0, 0.0, 0.0))

    def _run_takeoff(self) -> None:
        # PX4's Takeoff mode climbs once armed, then holds (AUTO.LOITER) at the altitude.
        v = self.vehicle
        if self.mode != "TAKEOFF" or not self.armed:
            return
        north, east, altitude = self.takeoff_target
        v.target = PathTarget("Endpoint", (north, east, -altitude))
        if abs(v.ned[2] + altitude) < 0.2:
            self.set_mode("GUIDED")

    def _offboard_signal(self, now: float) -> bool:
        """PX4's offboard "proof of life": setpoints > 2 Hz, unbroken for a second."""
        fresh = now - self.setpoint_at <= OFFBOARD_MAX_GAP_S
        return fresh and now - self.setpoint_stream_since >= OFFBOARD_WARMUP_S

    def _offboard_watch(self, now: float) -> None:
        if self.mode != "OFFBOARD" or now - self.setpoint_at <= self.params["COM_OF_LOSS_T"]:
            return
        # COM_OF_LOSS_T without a setpoint: PX4 leaves OFFBOARD for its loss action (hold).
        self.statustext(mavlink.MAV_SEVERITY_CRITICAL, "Failsafe: offboard signal lost, holding")
        self.set_mode("GUIDED" if self.has_position else "LAND")

    def _sync_vehicle_mode(self) -> None:
        # The kinematic model flies its target in any of its autonomous modes.
        flying = self.armed and self.mode in FLYING_MODES
        self.vehicle.flight_mode = "PositionHold" if flying else "Manual"

    def _ned_of(self, frame: int, x: float, y: float, z: float) -> tuple[float, float, float]:
        """A position in a MAVLink frame → the vehicle's NED (alt above home)."""
        v = self.vehicle
        if frame in (mavlink.MAV_FRAME_LOCAL_NED,):
            return x, y, z
        if frame in (mavlink.MAV_FRAME_GLOBAL, mavlink.MAV_FRAME_GLOBAL_INT):
            z = z - v.home[2]
        if x == 0 and y == 0:
            north, east = v.ned[0], v.ned[1]
        else:
            north, east, _ = lla_to_ned(x, y, v.home[2], v.home)
        return north, east, -z

    # --- input ------------------------------------------------------------------------
    def receive(self, data: bytes, now: float) -> None:
        if self.booting:
            return
        self._rx_now = now
        for msg in self.codec.feed(data):
            if (
                self.params["SIM_LOSS_PCT"]
                and self._rng.random() * 100 < self.params["SIM_LOSS_PCT"]
            ):
                self.stats.lost_in += 1  # a weak radio link: the message never arrived
                continue
            self.stats.messages_in += 1
            if msg.get_type() == "HEARTBEAT":
                self.gcs_heard = now
                self.gcs = (msg.get_srcSystem(), msg.get_srcComponent())
            try:
                self._handle(msg, now)
            except Exception:  # a message the model cannot apply must not stop the board
                log.exception("could not apply %s", msg.get_type())

    def _for_me(self, msg: Any) -> bool:
        target = getattr(msg, "target_system", 0)
        return target in (0, SYSTEM_ID)

    def _handle(self, msg: Any, now: float) -> None:
        kind = msg.get_type()
        if not self._for_me(msg):
            return
        if kind == "COMMAND_LONG":
            self._command(
                msg.command,
                [
                    msg.param1,
                    msg.param2,
                    msg.param3,
                    msg.param4,
                    msg.param5,
                    msg.param6,
                    msg.param7,
                ],
                None,
            )
        elif kind == "COMMAND_INT":
            params = [msg.param1, msg.param2, msg.param3, msg.param4, msg.x, msg.y, msg.z]
            self._command(msg.command, params, msg.frame)
        elif kind == "SET_MODE":
            name = self._custom_mode_name(msg.custom_mode)
            if name is not None:
                self.request_mode(name)  # no ACK for SET_MODE: the HEARTBEAT tells
        elif kind == "SET_POSITION_TARGET_GLOBAL_INT":
            self._setpoint(
                msg.coordinate_frame, msg.type_mask, msg.lat_int / 1e7, msg.lon_int / 1e7, msg.alt
            )
        elif kind == "SET_POSITION_TARGET_LOCAL_NED":
            self._setpoint(msg.coordinate_frame, msg.type_mask, msg.x, msg.y, msg.z)
        elif kind == "REQUEST_DATA_STREAM":
            self._data_stream(msg.req_stream_id, msg.req_message_rate, msg.start_stop)
        elif kind.startswith("MISSION_") or kind == "MISSION_ITEM":
            self._mission_message(kind, msg, now)
        elif kind.startswith("PARAM_"):
            self._param_message(kind, msg)
        elif kind.startswith("OPEN_DRONE_ID_") and self.remote_id is not None:
            self.remote_id.consume(msg, now)
        elif kind.startswith("LOG_"):
            self.flight_logs.handle(kind, msg, self._send)

    # --- commands ---------------------------------------------------------------------
    def _command(self, command: int, p: list[float], frame: int | None) -> None:
        self.stats.commands += 1
        if command == int(self.params["SIM_CMD_MUTE"]) and command != 0:
            self.stats.muted += 1
            return  # the fault knob: this vehicle never answers that command
        handler = {
            mavlink.MAV_CMD_COMPONENT_ARM_DISARM: self._cmd_arm,
            mavlink.MAV_CMD_DO_SET_MODE: self._cmd_set_mode,
            mavlink.MAV_CMD_NAV_TAKEOFF: self._cmd_takeoff,
            mavlink.MAV_CMD_NAV_LAND: self._cmd_land,
            mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH: lambda p, f: self.request_mode("RTL"),
            mavlink.MAV_CMD_MISSION_START: self._cmd_mission_start,
            mavlink.MAV_CMD_DO_REPOSITION: self._cmd_reposition,
            mavlink.MAV_CMD_SET_MESSAGE_INTERVAL: self._cmd_interval,
            mavlink.MAV_CMD_REQUEST_MESSAGE: self._cmd_request_message,
            mavlink.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES: self._cmd_capabilities,
            mavlink.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN: self._cmd_reboot,
            mavlink.MAV_CMD_DO_SET_ROI_LOCATION: self._cmd_roi_location,
            mavlink.MAV_CMD_DO_SET_ROI_NONE: self._cmd_roi_none,
        }.get(command)
        if handler is None:
            self._ack(command, mavlink.MAV_RESULT_UNSUPPORTED)
            return
        result = handler(p, frame)
        if result is not None:
            self._ack(command, result)

    def _cmd_arm(self, p: list[float], frame: int | None) -> int:
        force = abs(p[1] - FORCE_MAGIC) < 0.5
        if p[0] >= 0.5:
            if self.armed:
                return mavlink.MAV_RESULT_ACCEPTED
            reason = None if force else self.arming_refusal()
            if reason is not None:
                self.statustext(mavlink.MAV_SEVERITY_CRITICAL, reason)
                return mavlink.MAV_RESULT_DENIED
            self._set_armed(True)
            self.statustext(mavlink.MAV_SEVERITY_INFO, "Arming motors")
            return mavlink.MAV_RESULT_ACCEPTED
        if not self.armed:
            return mavlink.MAV_RESULT_ACCEPTED
        if self.vehicle.airborne and not force:
            self.statustext(mavlink.MAV_SEVERITY_CRITICAL, "Disarm: vehicle is flying")
            return mavlink.MAV_RESULT_DENIED
        self._set_armed(False)
        self.statustext(mavlink.MAV_SEVERITY_INFO, "Disarming motors")
        return mavlink.MAV_RESULT_ACCEPTED

    def arming_refusal(self) -> str | None:
        """The failing pre-arm check, worded as the autopilot words it (None: arms)."""
        percent = self.vehicle.remaining * 100
        limit = self.params["BATT_CRT_PCT"]
        if self.px4:
            if percent < limit:
                return f"Arming denied: battery critical {percent:.0f}% < {limit:g}%"
            if self.mode in POSITION_MODES and not self.has_position:
                return f"Arming denied: {PX4_MODE_NAMES[self.mode]} mode needs global position"
            return None
        if percent < limit:
            return f"PreArm: Battery critical {percent:.0f}% < {limit:g}%"
        if self.mode in NOT_ARMABLE:
            return f"Arm: Mode {self.mode} not armable"
        if self.mode in POSITION_MODES and not self.has_position:
            return "PreArm: Need Position Estimate"
        return self._remote_id_refusal()

    def _remote_id_refusal(self) -> str | None:
        """ArduPilot's pre-arm check on its Remote ID module's OPEN_DRONE_ID_ARM_STATUS."""
        if self.remote_id is None:
            return None
        status, error = self.remote_id.arm_status()
        return None if status == 0 else f"PreArm: OpenDroneID: {error}"

    @property
    def px4(self) -> bool:
        return self.autopilot == "px4"

    def _custom_mode_name(self, custom_mode: int) -> str | None:
        if self.px4:
            return PX4_TO_INTERNAL.get(((custom_mode >> 16) & 0xFF, (custom_mode >> 24) & 0xFF))
        return MODE_NAMES.get(custom_mode)

    def _cmd_set_mode(self, p: list[float], frame: int | None) -> int:
        if self.px4:
            internal = PX4_TO_INTERNAL.get((int(p[1]), int(p[2])))
            if not int(p[0]) & mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED or internal is None:
                return mavlink.MAV_RESULT_DENIED
            return self.request_mode(internal)
        name = MODE_NAMES.get(int(p[1]))
        if not int(p[0]) & mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED or name is None:
            return mavlink.MAV_RESULT_DENIED
        return self.request_mode(name)

    def _cmd_takeoff(self, p: list[float], frame: int | None) -> int:
        if self.px4:
            return self._px4_takeoff(p[6])
        # ArduCopter: a take-off only in GUIDED, armed, on the ground, to param7 above home.
        if self.mode != "GUIDED" or not self.armed:
            self.statustext(mavlink.MAV_SEVERITY_WARNING, "Takeoff: arm in GUIDED first")
            return mavlink.MAV_RESULT_FAILED
        if self.vehicle.airborne:
            return mavlink.MAV_RESULT_FAILED
        altitude = p[6]
        if not altitude > 0:
            return mavlink.MAV_RESULT_DENIED
        v = self.vehicle
        v.target = PathTarget("Endpoint", (v.ned[0], v.ned[1], -altitude))
        return mavlink.MAV_RESULT_ACCEPTED

    def _px4_takeoff(self, altitude_msl: float) -> int:
        """PX4: Takeoff mode from any mode, to param7 metres above mean sea level (NaN:
        MIS_TAKEOFF_ALT above home); disarmed it waits in Takeoff mode for the arming."""
        v = self.vehicle
        if math.isfinite(altitude_msl):
            altitude = altitude_msl - v.home[2]
        else:
            altitude = self.params["MIS_TAKEOFF_ALT"]
        if not altitude > 0:
            return mavlink.MAV_RESULT_DENIED
        if self.mode_refusal("TAKEOFF") is not None:
            self.statustext(
                mavlink.MAV_SEVERITY_CRITICAL, "Takeoff denied! Please disarm and retry"
            )
            return mavlink.MAV_RESULT_TEMPORARILY_REJECTED
        self.takeoff_target = (v.ned[0], v.ned[1], altitude)
        self.set_mode("TAKEOFF")
        return mavlink.MAV_RESULT_ACCEPTED

    def _cmd_land(self, p: list[float], frame: int | None) -> int:
        lat, lon = p[4], p[5]
        if frame is not None:
            lat, lon = lat / 1e7, lon / 1e7
        self.set_mode("LAND")
        if lat and lon and math.isfinite(lat) and math.isfinite(lon):
            north, east, _ = lla_to_ned(lat, lon, self.vehicle.home[2], self.vehicle.home)
            self.vehicle.target = PathTarget("Land", (north, east, 0.0))
        return mavlink.MAV_RESULT_ACCEPTED

    def _cmd_mission_start(self, p: list[float], frame: int | None) -> int:
        reason = self.mode_refusal("AUTO")
        if self.px4 and reason is None and not self.armed:
            # PX4 arms on MISSION_START, through its pre-arm checks.
            reason = self.arming_refusal()
        if reason is not None:
            self.statustext(mavlink.MAV_SEVERITY_CRITICAL, reason)
            # PX4 denies a mission start; ArduPilot's failed AUTO switch is FAILED.
            return mavlink.MAV_RESULT_DENIED if self.px4 else mavlink.MAV_RESULT_FAILED
        first = int(p[0]) if math.isfinite(p[0]) and p[0] >= 0 else self.current
        self.current = min(max(first, self.first_seq), len(self.mission) - 1)
        if self.px4 and not self.armed:
            self._set_armed(True)
        self.set_mode("AUTO")
        self.item_started = False
        return mavlink.MAV_RESULT_ACCEPTED

    def _cmd_reposition(self, p: list[float], frame: int | None) -> int:
        """PX4's MAV_CMD_DO_REPOSITION: with the CHANGE_MODE flag it switches to Hold,
        and in Hold while armed it flies to the position (lat/lon 0 or NaN: stay)."""
        flags = int(p[1]) if math.isfinite(p[1]) else 0
        change_mode = flags & mavlink.MAV_DO_REPOSITION_FLAGS_CHANGE_MODE
        if change_mode and self.mode != "GUIDED":
            result = self.request_mode("GUIDED")
            if result != mavlink.MAV_RESULT_ACCEPTED:
                return result
        if not self.armed or self.mode != "GUIDED":
            # PX4 takes the command and keeps the point for Hold; nothing moves meanwhile.
            return mavlink.MAV_RESULT_ACCEPTED
        lat, lon = (p[4] / 1e7, p[5] / 1e7) if frame is not None else (p[4], p[5])
        if not (math.isfinite(lat) and math.isfinite(lon)):
            lat = lon = 0.0
        frame = mavlink.MAV_FRAME_GLOBAL if frame is None else frame  # COMMAND_LONG: AMSL
        z = p[6]
        if not math.isfinite(z):  # NaN altitude: keep the current one
            z = -self.vehicle.ned[2]
            if frame in (mavlink.MAV_FRAME_GLOBAL, mavlink.MAV_FRAME_GLOBAL_INT):
                z += self.vehicle.home[2]
        self.vehicle.set_path_desired("Endpoint", self._ned_of(frame, lat, lon, z))
        return mavlink.MAV_RESULT_ACCEPTED

    def _cmd_roi_location(self, p: list[float], frame: int | None) -> int:
        """MAV_CMD_DO_SET_ROI_LOCATION (COMMAND_INT or COMMAND_LONG): both autopilots take
        it armed or not and turn the nose toward it while they fly; a location that is no
        place on Earth is refused (ArduPilot FAILED, PX4 DENIED)."""
        lat, lon = (p[4] / 1e7, p[5] / 1e7) if frame is not None else (p[4], p[5])
        if not _valid_latlon(lat, lon):
            self.statustext(mavlink.MAV_SEVERITY_WARNING, "ROI: invalid location")
            return mavlink.MAV_RESULT_DENIED if self.px4 else mavlink.MAV_RESULT_FAILED
        v = self.vehicle
        north, east, _ = lla_to_ned(lat, lon, v.home[2], v.home)
        v.roi = (north, east)
        return mavlink.MAV_RESULT_ACCEPTED

    def _cmd_roi_none(self, p: list[float], frame: int | None) -> int:
        self.vehicle.roi = None
        return mavlink.MAV_RESULT_ACCEPTED

    def _cmd_interval(self, p: list[float], frame: int | None) -> int:
        if self.params["SIM_MSGINT_OFF"]:
            return mavlink.MAV_RESULT_UNSUPPORTED  # as firmware older than the command
        name = self._stream_name(int(p[0]))
        if name is None:
            return mavlink.MAV_RESULT_UNSUPPORTED if int(p[0]) else mavlink.MAV_RESULT_DENIED
        interval_us = p[1]
        if interval_us < 0:
            self.intervals.pop(name, None)
        elif interval_us > 0:
            self.intervals[name] = interval_us / 1e6
        self.next_due.pop(name, None)
        return mavlink.MAV_RESULT_ACCEPTED

    def _stream_name(self, message_id: int) -> str | None:
        """The streamable message of this id that this autopilot sends (None: not one)."""
        name = STREAM_IDS.get(message_id)
        only = AUTOPILOT_ONLY.get(name or "")
        return None if only is not None and only != self.autopilot else name

    def _cmd_request_message(self, p: list[float], frame: int | None) -> int | None:
        name = self._stream_name(int(p[0]))
        if name is None:
            return mavlink.MAV_RESULT_UNSUPPORTED
        self._ack(mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAV_RESULT_ACCEPTED)
        self._emit(name)
        return None

    def _cmd_capabilities(self, p: list[float], frame: int | None) -> int | None:
        self._ack(mavlink.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES, mavlink.MAV_RESULT_ACCEPTED)
        self._emit("AUTOPILOT_VERSION")
        return None

    def _cmd_reboot(self, p: list[float], frame: int | None) -> int | None:
        if int(p[0]) != 1:
            return mavlink.MAV_RESULT_UNSUPPORTED
        if self.vehicle.airborne:
            return mavlink.MAV_RESULT_DENIED
        self._ack(mavlink.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN, mavlink.MAV_RESULT_ACCEPTED)
        # Reboot on a later tick than this one, once serve() has written the ACK out.
        self._reboot_due = self._rx_now
        return None

    def reboot(self) -> None:
        self._reboot_due = None
        self.stats.reboots += 1
        self.vehicle.reboot()
        self._booting_until = self.vehicle.time + BOOT_TIME_S
        self.mode = "STABILIZE"
        self.intervals.clear()
        self._default_streams()
        self.next_due.clear()
        self.upload = None
        self.codec = MavlinkCodec(SYSTEM_ID, COMPONENT_ID)
        self.decoder = self.codec
        if self.on_reboot is not None:
            self.on_reboot()
        # The ACK already queued still reaches a TCP peer only if the link survives.
        self._out.clear()

    def _setpoint(self, frame: int, mask: int, x: float, y: float, z: float) -> None:
        """SET_POSITION_TARGET_*: ArduCopter flies them in GUIDED; PX4 only in OFFBOARD,
        and every one it gets (any mode) keeps its offboard signal alive."""
        if self.px4:
            self._note_setpoint(self._rx_now)
            flying = self.mode == "OFFBOARD"
        else:
            flying = self.mode == "GUIDED"
        if not flying or not self.armed or mask & 0b111:
            self.stats.setpoints_ignored += 1
            return
        self.stats.setpoints += 1
        north, east, down = self._ned_of(frame, x, y, z)
        self.vehicle.set_path_desired("Endpoint", (north, east, down))

    def _note_setpoint(self, now: float) -> None:
        if now - self.setpoint_at > OFFBOARD_MAX_GAP_S:
            self.setpoint_stream_since = now  # a new stream: its second of warm-up starts
        self.setpoint_at = now

    def _data_stream(self, stream: int, rate: int, start: int) -> None:
        if stream == mavlink.MAV_DATA_STREAM_ALL:
            names = [n for group in STREAM_GROUPS.values() for n in group]
        else:
            names = list(STREAM_GROUPS.get(stream, ()))
        for name in names:
            if start and rate > 0:
                self.intervals[name] = 1.0 / rate
            else:
                self.intervals.pop(name, None)
            self.next_due.pop(name, None)

    # --- parameters -------------------------------------------------------------------
    def _param_message(self, kind: str, msg: Any) -> None:
        names = list(self.params)
        if kind == "PARAM_SET":
            name = _text(msg.param_id)
            if name not in self.params:
                self.statustext(mavlink.MAV_SEVERITY_WARNING, f"Unknown parameter {name}")
                return
            self.params[name] = float(msg.param_value)
            self._param_value(name)
        elif kind == "PARAM_REQUEST_READ":
            name = _text(msg.param_id)
            if msg.param_index >= 0 and msg.param_index < len(names):
                name = names[msg.param_index]
            if name in self.params:
                self._param_value(name)
        elif kind == "PARAM_REQUEST_LIST":
            for name in names:
                self._param_value(name)

    def _param_value(self, name: str) -> None:
        names = list(self.params)
        self._send(
            "param_value",
            name.encode(),
            self.params[name],
            mavlink.MAV_PARAM_TYPE_REAL32,
            len(names),
            names.index(name),
        )

    # --- mission protocol -------------------------------------------------------------
    def _mission_message(self, kind: str, msg: Any, now: float) -> None:
        if getattr(msg, "mission_type", 0) != mavlink.MAV_MISSION_TYPE_MISSION:
            if kind in ("MISSION_COUNT", "MISSION_REQUEST_LIST", "MISSION_CLEAR_ALL"):
                # Fence and rally lists are not kept: say so, as a vehicle without them does.
                if kind == "MISSION_REQUEST_LIST":
                    self._send("mission_count", *self.gcs, 0, msg.mission_type)
                else:
                    self._mission_ack(mavlink.MAV_MISSION_UNSUPPORTED, msg.mission_type)
            return
        if kind == "MISSION_COUNT":
            # Both autopilots take a new mission in flight, AUTO too: it runs from its start.
            self.upload = _Upload(msg.count)
            if msg.count == 0:
                self._finish_upload()
            else:
                self._request_item(now)
        elif kind in ("MISSION_ITEM_INT", "MISSION_ITEM"):
            self._receive_item(kind, msg, now)
        elif kind == "MISSION_REQUEST_LIST":
            self._send("mission_count", *self.gcs, len(self.mission), 0)
        elif kind in ("MISSION_REQUEST_INT", "MISSION_REQUEST"):
            self._send_item(msg.seq, legacy=kind == "MISSION_REQUEST")
        elif kind == "MISSION_CLEAR_ALL":
            self.mission = []
            self.current = self.first_seq
            self._mission_ack(mavlink.MAV_MISSION_ACCEPTED)
        elif kind == "MISSION_SET_CURRENT":
            if 0 <= msg.seq < len(self.mission):
                self.current = max(msg.seq, self.first_seq)
                self.item_started = False
                self._emit("MISSION_CURRENT")

    def _mission_ack(self, result: int, mission_type: int = 0) -> None:
        self._send("mission_ack", *self.gcs, result, mission_type)

    def _request_item(self, now: float) -> None:
        upload = self.upload
        assert upload is not None
        upload.asked_at = now
        seq = len(upload.items)
        if upload.legacy:
            self._send("mission_request", *self.gcs, seq, 0)
        else:
            self._send("mission_request_int", *self.gcs, seq, 0)

    def _receive_item(self, kind: str, msg: Any, now: float) -> None:
        upload = self.upload
        if upload is None:
            return
        if msg.seq != len(upload.items):
            if msg.seq < len(upload.items):
                return  # a resend of one we have
            self._mission_ack(mavlink.MAV_MISSION_INVALID_SEQUENCE)
            return
        x, y = float(msg.x), float(msg.y)
        if kind == "MISSION_ITEM_INT":
            scale = 1e4 if msg.frame == mavlink.MAV_FRAME_LOCAL_NED else 1e7
            x, y = x / scale, y / scale
        else:
            upload.legacy = True
        if msg.frame not in (
            mavlink.MAV_FRAME_GLOBAL,
            mavlink.MAV_FRAME_GLOBAL_INT,
            mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT,
            mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
            mavlink.MAV_FRAME_GLOBAL_TERRAIN_ALT,
            mavlink.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT,
            mavlink.MAV_FRAME_LOCAL_NED,
            mavlink.MAV_FRAME_MISSION,
        ):
            self.upload = None
            self._mission_ack(mavlink.MAV_MISSION_UNSUPPORTED_FRAME)
            return
        upload.items.append(
            MissionItem(
                msg.seq,
                msg.frame,
                msg.command,
                (msg.param1, msg.param2, msg.param3, msg.param4),
                x,
                y,
                float(msg.z),
                msg.autocontinue,
            )
        )
        upload.tries = 0
        if len(upload.items) == upload.count:
            self._finish_upload()
        else:
            self._request_item(now)

    def _finish_upload(self) -> None:
        upload = self.upload
        assert upload is not None
        self.mission = upload.items
        self.upload = None
        self.current = self.first_seq
        self.item_started = False
        self.mission_done = False
        self.stats.mission_uploads += 1
        self._mission_ack(mavlink.MAV_MISSION_ACCEPTED)
        log.info("mission of %d items accepted", len(self.mission))

    def _send_item(self, seq: int, *, legacy: bool) -> None:
        if not 0 <= seq < len(self.mission):
            self._mission_ack(mavlink.MAV_MISSION_INVALID_SEQUENCE)
            return
        item = self.mission[seq] if seq >= self.first_seq else self._home_item()
        wire = item.wire()
        common = (
            wire["frame"],
            item.command,
            int(seq == self.current),
            item.autocontinue,
            *item.params,
        )
        if legacy:
            self._send("mission_item", *self.gcs, seq, *common, item.x, item.y, item.z, 0)
        else:
            self._send("mission_item_int", *self.gcs, seq, *common, wire["x"], wire["y"], item.z, 0)

    def _home_item(self) -> MissionItem:
        """ArduPilot's item 0: home, whatever was uploaded there, at its altitude AMSL."""
        lat, lon, alt = self.vehicle.home
        return MissionItem(
            0, mavlink.MAV_FRAME_GLOBAL, mavlink.MAV_CMD_NAV_WAYPOINT, (0, 0, 0, 0), lat, lon, alt
        )

    def _upload_watchdog(self, now: float) -> None:
        upload = self.upload
        if upload is None or now - upload.asked_at < UPLOAD_RETRY_S:
            return
        upload.tries += 1
        if upload.tries > UPLOAD_RETRIES:
            self.upload = None
            self._mission_ack(mavlink.MAV_MISSION_OPERATION_CANCELLED)
            self.statustext(mavlink.MAV_SEVERITY_WARNING, "Mission upload timed out")
            return
        self._request_item(now)

    # --- AUTO mode --------------------------------------------------------------------
    def _run_mission(self) -> None:
        if self.mode != "AUTO" or not self.armed or self.mission_done:
            return
        if self.current >= len(self.mission):
            return  # nothing flyable on board (cleared, or ArduPilot's home alone)
        v = self.vehicle
        item = self.mission[self.current]
        if not self.item_started:
            self.item_started = True
            self.hold_until = None
            self._start_item(item)
            self._emit("MISSION_CURRENT")
        if not self._item_reached(item):
            return
        hold = (
            item.params[0]
            if item.command in (mavlink.MAV_CMD_NAV_WAYPOINT, mavlink.MAV_CMD_NAV_LOITER_TIME)
            else 0.0
        )
        if self.hold_until is None:
            self.hold_until = v.time + max(hold, 0.0)
        if v.time < self.hold_until:
            return
        self._send("mission_item_reached", item.seq)
        if self.current + 1 >= len(self.mission):
            self.mission_done = True
            self.statustext(mavlink.MAV_SEVERITY_INFO, "Mission complete")
            if item.command not in (mavlink.MAV_CMD_NAV_LAND, mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH):
                v.target = PathTarget("HoldPosition", (v.ned[0], v.ned[1], v.ned[2]))
            return
        self.current += 1
        self.item_started = False

    def _start_item(self, item: MissionItem) -> None:
        v = self.vehicle
        command = item.command
        if command == mavlink.MAV_CMD_NAV_TAKEOFF:
            v.target = PathTarget("Endpoint", (v.ned[0], v.ned[1], -abs(item.z)))
        elif command in (
            mavlink.MAV_CMD_NAV_WAYPOINT,
            mavlink.MAV_CMD_NAV_LOITER_TIME,
            mavlink.MAV_CMD_NAV_LOITER_UNLIM,
        ):
            v.target = PathTarget("Endpoint", self._ned_of(item.frame, item.x, item.y, item.z))
        elif command == mavlink.MAV_CMD_NAV_LAND:
            north, east, _ = self._ned_of(item.frame, item.x, item.y, 0.0)
            v.target = PathTarget("Land", (north, east, 0.0))
        elif command == mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH:
            v.target = PathTarget("Land", (0.0, 0.0, 0.0))
        elif command == mavlink.MAV_CMD_DO_CHANGE_SPEED:
            # param2: m/s from here on; -2 back to the default, -1 (or 0) no change.
            speed = item.params[1]
            if speed > 0:
                v.config.max_horizontal = speed
            elif speed == -2:
                v.config.max_horizontal = self.cruise_speed
        elif command == mavlink.MAV_CMD_DO_SET_CAM_TRIGG_DIST:
            self.trigger_distance = max(item.params[0], 0.0)
            self.trigger_at = None
        elif command == mavlink.MAV_CMD_DO_SET_ROI_LOCATION:
            self._cmd_roi_location([*item.params, item.x * 1e7, item.y * 1e7, item.z], item.frame)
        elif command == mavlink.MAV_CMD_DO_SET_ROI_NONE:
            v.roi = None
        # Other DO_* and CONDITION_* items take effect at once and change nothing here.

    def _camera_trigger(self) -> None:
        """Distance triggering: a shot at the start and every `trigger_distance` metres
        flown, reported as CAMERA_TRIGGER (image index counts from 0)."""
        if self.trigger_distance <= 0 or self.mode != "AUTO":
            return
        here = (self.vehicle.ned[0], self.vehicle.ned[1])
        if self.trigger_at is not None and math.dist(here, self.trigger_at) < self.trigger_distance:
            return
        self.trigger_at = here
        self._send("camera_trigger", int(self.vehicle.time * 1e6), self.camera_triggers)
        self.camera_triggers += 1

    def _item_reached(self, item: MissionItem) -> bool:
        v = self.vehicle
        if item.command == mavlink.MAV_CMD_NAV_LOITER_UNLIM:
            return False
        if item.command in (mavlink.MAV_CMD_NAV_LAND, mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH):
            return not v.airborne and abs(v.velocity[2]) < 0.05
        if item.command in NAV_POSITION_ITEMS:
            return math.dist(v.ned, v.target.end) < ACCEPTANCE_RADIUS_M
        return True

    # --- time -------------------------------------------------------------------------
    def tick(self, now: float) -> None:
        if self._last_real is None:
            self._last_real = now
        if self._reboot_due is not None and now > self._reboot_due:
            self.reboot()
        real_dt = max(0.0, now - self._last_real)
        self._last_real = now
        sim_dt = min(real_dt * self.time_scale, 1.0)
        self._wind_watch(now)
        while sim_dt > 1e-9:
            dt = min(sim_dt, 0.05)
            self._run_mission()
            self._run_takeoff()
            self._run_rtl()
            self.vehicle.step(dt)
            self._camera_trigger()
            self._auto_disarm()
            self.flight_logs.record(self.vehicle, self.mode, self.armed, dt)
            sim_dt -= dt
        if self.booting:
            return
        if self.remote_id is not None:
            self.remote_id.tick(now)
        self._upload_watchdog(now)
        self._offboard_watch(now)
        self._battery_watch()
        if self._send_heartbeat_now or now - self._last_heartbeat >= HEARTBEAT_S:
            self._send_heartbeat_now = False
            self._last_heartbeat = now
            self._heartbeat()
        # A log download asked for goes on whoever listens (it was asked for).
        self.flight_logs.pump(self._send)
        if now - self.gcs_heard > self.link_timeout_s:
            return  # nobody there: only heartbeats, as ArduPilot on a quiet port
        self._stream(now)
        self._junk(now)

    def _wind_watch(self, now: float) -> None:
        """The wind file's new wind into the parameters, the parameters into the vehicle."""
        changed = self.wind_file.changed(now) if self.wind_file is not None else None
        if changed is not None:
            self.params["SIM_WIND_SPD"], self.params["SIM_WIND_DIR"] = changed
        speed = max(0.0, self.params["SIM_WIND_SPD"])
        self.vehicle.wind = wind_ned(speed, self.params["SIM_WIND_DIR"])

    def _auto_disarm(self) -> None:
        v = self.vehicle
        landing = (
            self.mode == "LAND"
            or (self.mode == "RTL" and self.rtl_phase == "land")
            or (
                self.mode == "AUTO"
                and self.current < len(self.mission)
                and self.mission[self.current].command
                in (mavlink.MAV_CMD_NAV_LAND, mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH)
            )
        )
        if not self.armed or not landing or v.airborne:
            self._landed_at = None
            return
        if self._landed_at is None:
            self._landed_at = v.time
        elif v.time - self._landed_at >= self.params["DISARM_DELAY"]:
            self._set_armed(False)
            self.statustext(mavlink.MAV_SEVERITY_INFO, "Disarming motors (landed)")

    def _battery_watch(self) -> None:
        critical = self.vehicle.remaining * 100 < self.params["BATT_CRT_PCT"]
        if critical and not self._was_critical:
            self.statustext(mavlink.MAV_SEVERITY_CRITICAL, "Battery critical")
        self._was_critical = critical

    def _heartbeat(self) -> None:
        base = mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | mavlink.MAV_MODE_FLAG_STABILIZE_ENABLED
        if self.mode in ("GUIDED", "AUTO", "RTL", "LAND", "TAKEOFF", "OFFBOARD"):
            base |= mavlink.MAV_MODE_FLAG_GUIDED_ENABLED
        if self.mode == "AUTO":
            base |= mavlink.MAV_MODE_FLAG_AUTO_ENABLED
        if self.armed:
            base |= mavlink.MAV_MODE_FLAG_SAFETY_ARMED
        status = mavlink.MAV_STATE_ACTIVE if self.armed else mavlink.MAV_STATE_STANDBY
        if self._was_critical:
            status = mavlink.MAV_STATE_CRITICAL
        if self.px4:
            main, sub = PX4_MODES.get(self.mode, PX4_MODES["GUIDED"])
            autopilot, custom = mavlink.MAV_AUTOPILOT_PX4, (main << 16) | (sub << 24)
        else:
            autopilot, custom = mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, COPTER_MODES[self.mode]
        self._send("heartbeat", mavlink.MAV_TYPE_QUADROTOR, autopilot, base, custom, status)
        if self.remote_id is not None:
            self._module_heartbeat()

    def _module_heartbeat(self) -> None:
        """A MAVLink Remote ID module beats once a second as ArduRemoteID does: type ODID,
        autopilot ArduPilot, nothing armed; the flight controller forwards it."""
        self._out += self.module_codec.encode(
            "heartbeat",
            mavlink.MAV_TYPE_ODID,
            mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA,
            0,
            0,
            mavlink.MAV_STATE_ACTIVE,
        )

    def _stream(self, now: float) -> None:
        board = self.vehicle.time
        for name, interval in self.intervals.items():
            due = self.next_due.get(name)
            if due is not None and board < due:
                continue
            if now - self.last_sent_wall.get(name, -math.inf) < 1.0 / MAX_WALL_HZ:
                continue
            self._emit(name)
            self.last_sent_wall[name] = now
            nxt = (due if due is not None else board) + interval
            self.next_due[name] = nxt if nxt > board else board + interval

    def _junk(self, now: float) -> None:
        rate = self.params["SIM_JUNK_RATE"]
        if rate <= 0 or now < self._junk_due:
            return
        self._junk_due = now + 1.0 / rate
        good = self.codec.encode("heartbeat", 2, 3, 0, 0, 0)
        bad_crc = bytearray(good)
        bad_crc[-1] ^= 0xFF
        unknown = bytearray(good)
        unknown[7:10] = b"\x77\x77\x00"  # message id 30583: in no dialect
        self._out += bytes(bad_crc) + bytes(unknown)
        self.stats.junk_sent += 2

    def _emit(self, name: str) -> None:
        """Send one streamed message, its fields from `STREAMED[name]` (none: nothing sent)."""
        fields = STREAMED[name](self)
        if fields is not None:
            self._send(name.lower(), *fields)


def _valid_latlon(lat: float, lon: float) -> bool:
    finite = math.isfinite(lat) and math.isfinite(lon)
    return finite and abs(lat) <= 90 and abs(lon) <= 180 and (lat, lon) != (0.0, 0.0)


def _text(value: Any) -> str:
    if isinstance(value, bytes | bytearray):
        value = bytes(value).decode(errors="replace")
    return str(value).rstrip("\0")
