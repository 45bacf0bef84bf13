"""MAVLink driver for PX4 / ArduPilot flight controllers.

Layers, as for UAVTalk: `MavlinkCodec` is sans-I/O (bytes in, messages out, counted
drops), links are named by URL (`serial:`, `tcp://`, `udp://`), and
`MavlinkFlightController` owns one I/O thread that reads the link, tracks the vehicle's
heartbeat on a monotonic clock, sends the ground station's own heartbeat, resolves
COMMAND_ACKs and keeps `VehicleState` current. Listeners run on a dispatcher thread.

Telemetry mapping (listeners get both: the MAVLink message under its own name with its
own fields, so logs stay faithful, and the platform's object where one maps):

| MAVLink message      | platform object(s)                | fields                        |
|----------------------|-----------------------------------|-------------------------------|
| HEARTBEAT            | FlightStatus                      | Armed, FlightMode             |
| ATTITUDE             | AttitudeActual                    | Roll/Pitch/Yaw (deg), q1..q4  |
| LOCAL_POSITION_NED   | PositionActual, VelocityActual    | North, East, Down (m, m/s)    |
| GLOBAL_POSITION_INT  | GPSPosition (merged)              | Latitude/Longitude (1e7 deg), |
|                      |                                   | Altitude (m MSL), Heading, Groundspeed |
| GPS_RAW_INT          | GPSPosition (merged)              | Status, Satellites, HDOP, VDOP |
| SYS_STATUS           | FlightBatteryState (merged),      | Voltage, Current, Remaining;  |
|                      | SystemStats                       | CPULoad, RxErrors             |
| BATTERY_STATUS       | FlightBatteryState (merged)       | ConsumedEnergy (mAh), Voltage |
| SMART_BATTERY_INFO,  | (state: battery_serial, sent in   | serial_number, asked once per |
| BATTERY_INFO         | the heartbeat's battery.serial)   | vehicle session               |
| HIGHRES_IMU          | Accels, Gyros (deg/s),            | x, y, z, temperature;         |
|                      | Magnetometer, BaroAltitude        | Altitude, Pressure (kPa)      |
| WIND_COV (PX4),      | WindVelocityActual                | North, East, Down (m/s, the   |
| WIND (ArduPilot)     |                                   | air's velocity), Source       |
| (link, 1 Hz)         | FlightTelemetryStats              | Status, RxFailures, RxUnknown |

Commands: arming by COMMAND_LONG MAV_CMD_COMPONENT_ARM_DISARM (force = 21196 in param2),
take-off in GUIDED with MAV_CMD_NAV_TAKEOFF, MAV_CMD_NAV_LAND, goto by
SET_POSITION_TARGET_GLOBAL_INT (or LOCAL_NED with `goto_frame="local"`). A COMMAND_ACK
that is not ACCEPTED raises `CommandRejected` naming the MAV_RESULT; no ACK raises
`CommandTimeout`. Flight modes are ArduCopter's custom modes (GUIDED, AUTO, LAND, ...);
with a PX4 autopilot (told by its HEARTBEAT) the driver uses PX4's main/sub modes, takes
off to an AMSL altitude and flies to points with MAV_CMD_DO_REPOSITION (COMMAND_INT,
AMSL, CHANGE_MODE flag) in hold (LOITER). PX4 is not flown in OFFBOARD: that mode drops
to its fail-safe whenever a > 2 Hz setpoint stream pauses, while a reposition is one
acknowledged command that PX4 keeps flying on its own (onboard/README.md says more).
`point_at` sets or clears a region of interest with MAV_CMD_DO_SET_ROI_LOCATION /
MAV_CMD_DO_SET_ROI_NONE.
"""

from __future__ import annotations

import contextlib
import logging
import math
import queue
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from onboard.fc.base import (
    CommandTimeout,
    FlightControllerError,
    NotConnected,
)
from onboard.fc.driver import LinkDriver
from onboard.links import LinkDown, ReopeningLink
from onboard.navigation import euler_to_quaternion, ned_to_lla

log = logging.getLogger(__name__)

FORCE_MAGIC = 21196.0  # param2 of MAV_CMD_COMPONENT_ARM_DISARM that overrides checks
GCS_HEARTBEAT_S = 1.0
HEARTBEAT_TIMEOUT_S = 3.0  # ArduPilot's and PX4's GCS failsafes use 3-5 s
ACK_TIMEOUT_S = 3.0
COMMAND_TRIES = 3
# Position only: ignore velocity, acceleration, yaw and yaw rate (POSITION_TARGET_TYPEMASK).
POSITION_ONLY_MASK = 0x0FF8
COPTER_MODES = {name: number for number, name in mavutil.mode_mapping_acm.items()}
NOT_ARMABLE_MODES = ("LAND", "RTL", "AUTO")
# The platform's mode words → PX4's (hold is where PX4 flies to repositioned points).
PX4_NAMES = {"GUIDED": "LOITER", "AUTO": "MISSION", "STABILIZE": "MANUAL"}
# Wanted stream rates in Hz; SET_MESSAGE_INTERVAL per message, REQUEST_DATA_STREAM fallback.
DEFAULT_RATES: dict[str, float] = {
    "GLOBAL_POSITION_INT": 10.0,
    "LOCAL_POSITION_NED": 10.0,
    "ATTITUDE": 10.0,
    "HIGHRES_IMU": 5.0,
    "SYS_STATUS": 2.0,
    "GPS_RAW_INT": 2.0,
    "BATTERY_STATUS": 1.0,
    "MISSION_CURRENT": 1.0,
    "HOME_POSITION": 0.5,
    # The autopilot's wind estimate: PX4 sends WIND_COV, ArduPilot WIND; each refuses the
    # other's, which is then not asked for again.
    "WIND_COV": 1.0,
    "WIND": 1.0,
}
# REQUEST_DATA_STREAM groups (MAV_DATA_STREAM) that carry each message on ArduPilot.
DATA_STREAMS = {
    mavlink.MAV_DATA_STREAM_RAW_SENSORS: ("HIGHRES_IMU", "GPS_RAW_INT"),
    mavlink.MAV_DATA_STREAM_EXTENDED_STATUS: ("SYS_STATUS", "BATTERY_STATUS", "MISSION_CURRENT"),
    mavlink.MAV_DATA_STREAM_POSITION: ("GLOBAL_POSITION_INT", "LOCAL_POSITION_NED"),
    mavlink.MAV_DATA_STREAM_EXTRA1: ("ATTITUDE",),
    mavlink.MAV_DATA_STREAM_EXTRA3: ("WIND",),
}
# Platform object → the MAVLink messages it is built from (for objrequest).
PLATFORM_SOURCES = {
    "FlightStatus": ("HEARTBEAT",),
    "AttitudeActual": ("ATTITUDE",),
    "PositionActual": ("LOCAL_POSITION_NED",),
    "VelocityActual": ("LOCAL_POSITION_NED",),
    "GPSPosition": ("GLOBAL_POSITION_INT", "GPS_RAW_INT"),
    "FlightBatteryState": ("SYS_STATUS", "BATTERY_STATUS"),
    "SystemStats": ("SYS_STATUS",),
    "Accels": ("HIGHRES_IMU",),
    "Gyros": ("HIGHRES_IMU",),
    "Magnetometer": ("HIGHRES_IMU",),
    "BaroAltitude": ("HIGHRES_IMU",),
    "HomeLocation": ("HOME_POSITION",),
    "WindVelocityActual": ("WIND_COV", "WIND"),
}


# Messages naming the fitted battery by its serial_number, newest first: BATTERY_INFO
# (MAVLink development set) and SMART_BATTERY_INFO [MAVLink common].
BATTERY_IDENTITY = ("BATTERY_INFO", "SMART_BATTERY_INFO")


def battery_serial(m: Any) -> str | None:
    """The serial_number of a BATTERY_INFO / SMART_BATTERY_INFO (NUL-padded characters),
    None when empty."""
    raw = m.serial_number
    text = bytes(raw).decode(errors="replace") if isinstance(raw, bytes | bytearray) else raw
    text = str(text).split("\0", 1)[0].strip()
    return text or None


# The flight controller's log coming down (onboard.fc.mavlink_logs): bytes of a file, not
# telemetry; they go to the fetcher's handler only.
NOT_TELEMETRY = frozenset({"LOG_ENTRY", "LOG_DATA"})


def enum_name(enum: str, value: int) -> str:
    """`MAV_RESULT` 2 → "MAV_RESULT_DENIED" (the number itself when it is not in the enum)."""
    entry = mavlink.enums.get(enum, {}).get(value)
    return entry.name if entry is not None else f"{enum}_{value}"


def command_name(command: int) -> str:
    return enum_name("MAV_CMD", command)


# --- codec -------------------------------------------------------------------------------


@dataclass
class CodecStats:
    messages: int = 0
    bad_crc: int = 0
    unknown: int = 0
    bad_data: int = 0

    def as_dict(self) -> dict:
        return dict(self.__dict__)


# MAV_TYPEs of the components that share a vehicle's bus without flying it (MAVLink
# common.xml MAV_TYPE): their HEARTBEATs say nothing of the vehicle's state.
PERIPHERAL_TYPES = frozenset(
    (
        mavlink.MAV_TYPE_ANTENNA_TRACKER,
        mavlink.MAV_TYPE_GCS,
        mavlink.MAV_TYPE_ONBOARD_CONTROLLER,
        mavlink.MAV_TYPE_GIMBAL,
        mavlink.MAV_TYPE_ADSB,
        mavlink.MAV_TYPE_CAMERA,
        mavlink.MAV_TYPE_CHARGING_STATION,
        mavlink.MAV_TYPE_FLARM,
        mavlink.MAV_TYPE_SERVO,
        mavlink.MAV_TYPE_ODID,
        mavlink.MAV_TYPE_BATTERY,
        mavlink.MAV_TYPE_PARACHUTE,
        mavlink.MAV_TYPE_LOG,
        mavlink.MAV_TYPE_OSD,
        mavlink.MAV_TYPE_IMU,
        mavlink.MAV_TYPE_GPS,
        mavlink.MAV_TYPE_WINCH,
    )
)


class MavlinkCodec:
    """MAVLink 2 framing (pymavlink's parser, no I/O): `feed(bytes)` → good messages.

    Frames with a bad CRC, bytes that are no frame, and messages of ids this dialect does
    not know are counted in `stats` and dropped, never raised.
    """

    def __init__(self, system_id: int, component_id: int) -> None:
        self.mav = mavlink.MAVLink(None, srcSystem=system_id, srcComponent=component_id)
        self.mav.robust_parsing = True
        self.stats = CodecStats()
        self._lock = threading.Lock()

    def feed(self, data: bytes) -> list[Any]:
        try:
            parsed = self.mav.parse_buffer(data) or []
        except Exception as exc:  # a parser bug on hostile bytes must not stop the link
            self.stats.bad_data += 1
            log.debug("MAVLink parser error: %s", exc)
            return []
        good = []
        for msg in parsed:
            if isinstance(msg, mavlink.MAVLink_bad_data):
                if "CRC" in str(getattr(msg, "reason", "")):
                    self.stats.bad_crc += 1
                else:
                    self.stats.bad_data += 1
            elif isinstance(msg, mavlink.MAVLink_unknown):
                self.stats.unknown += 1
            else:
                self.stats.messages += 1
                good.append(msg)
        return good

    def encode(self, name: str, *args: Any, **kwargs: Any) -> bytes:
        """`encode("heartbeat", 6, 8, 0, 0, 4)`: one packed frame with the next sequence."""
        with self._lock:
            msg = getattr(self.mav, f"{name}_encode")(*args, **kwargs)
            wire = msg.pack(self.mav)
            self.mav.seq = (self.mav.seq + 1) % 256
            return bytes(wire)


def message_fields(msg: Any) -> dict:
    """A message's fields as plain JSON values (NaN → None, bytes → hex, arrays → lists)."""
    out = {}
    for name in msg.get_fieldnames():
        out[name] = _jsonable(getattr(msg, name))
    return out


def _jsonable(value: Any) -> Any:
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, bytes | bytearray):
        return value.hex()
    if isinstance(value, list | tuple):
        return [_jsonable(v) for v in value]
    return value


# --- links -------------------------------------------------------------------------------


def open_mavlink_link(url: str) -> ReopeningLink:
    """A reopening link: `serial:`, a device path, `tcp://`, `udp://` or `udpout://`."""
    return ReopeningLink(url.strip())


# --- errors ------------------------------------------------------------------------------


class CommandRejected(FlightControllerError):
    """A COMMAND_ACK whose result is not MAV_RESULT_ACCEPTED."""

    def __init__(self, command: int, result: int, detail: str = "") -> None:
        self.command = command
        self.result = result
        self.result_name = enum_name("MAV_RESULT", result)
        text = f"The flight controller refused {command_name(command)}: {self.result_name}"
        if detail:
            text += f" ({detail})"
        super().__init__(text)


# --- the driver --------------------------------------------------------------------------


@dataclass
class _AckWaiter:
    command: int
    event: threading.Event = field(default_factory=threading.Event)
    result: int | None = None


@dataclass
class _MessageWaiter:
    name: str
    event: threading.Event = field(default_factory=threading.Event)
    msg: Any = None


MessageHandler = Callable[[Any], None]


class MavlinkFlightController(LinkDriver):
    """FlightController over MAVLink 2 (see onboard.fc.base for the interface)."""

    protocol = "mavlink"

    def __init__(
        self,
        link_url: str,
        *,
        system_id: int = 255,
        component_id: int = mavlink.MAV_COMP_ID_MISSIONPLANNER,
        heartbeat_timeout_s: float = HEARTBEAT_TIMEOUT_S,
        ack_timeout_s: float = ACK_TIMEOUT_S,
        command_tries: int = COMMAND_TRIES,
        stream_rates: dict[str, float] | None = None,
        goto_frame: str = "global",
    ) -> None:
        if goto_frame not in ("global", "local"):
            raise ValueError("goto_frame must be 'global' or 'local'")
        self.link_url = link_url
        self._init_link_driver(open_mavlink_link(link_url), "mavlink")
        # MAVLink streams more objects than a UAVTalk board: a deeper listener queue.
        self._events = queue.Queue(maxsize=20_000)
        self.codec = MavlinkCodec(system_id, component_id)
        self.system_id = system_id
        self.heartbeat_timeout_s = heartbeat_timeout_s
        self.ack_timeout_s = ack_timeout_s
        self.command_tries = command_tries
        self.stream_rates = dict(DEFAULT_RATES if stream_rates is None else stream_rates)
        self.goto_frame = goto_frame
        self.target_system = 0
        self.target_component = 0
        self.autopilot: int | None = None
        self.stats.update(
            {
                "link_lost": 0,
                "connects": 0,
                "statustext": 0,
                "commands": 0,
                "command_timeouts": 0,
                "commands_refused": 0,
                "foreign": 0,
                "stream_fallbacks": 0,
                "handler_errors": 0,
            }
        )
        self._latest: dict[str, dict] = {}  # MAVLink message name → fields
        self._platform: dict[str, dict] = {}  # platform object name → merged fields
        self._values_lock = threading.Lock()
        self._handlers: list[MessageHandler] = []
        self._acks: list[_AckWaiter] = []
        self._msg_waiters: list[_MessageWaiter] = []
        self._waiters_lock = threading.Lock()
        self._command_lock = threading.Lock()
        self._statustexts: deque[tuple[float, int, str]] = deque(maxlen=20)
        self._last_vehicle_heartbeat = 0.0
        self._last_gcs_heartbeat = 0.0
        self._last_link_stats = 0.0

    # --- the protocol's part of the link skeleton (onboard/fc/driver.py) -----------------
    LINK_NAME = "MAVLink"
    THREAD_PREFIX = "mavlink"

    def add_message_handler(self, handler: MessageHandler) -> None:
        """Call handler(msg) on the I/O thread for every message from the vehicle
        (the native-mission protocol uses this); it must be quick and must not block."""
        self._handlers.append(handler)

    def remove_message_handler(self, handler: MessageHandler) -> None:
        with contextlib.suppress(ValueError):
            self._handlers.remove(handler)

    @property
    def decoder_stats(self) -> dict:
        return self.codec.stats.as_dict()

    def _on_new_line(self, now: float) -> None:
        self.codec = MavlinkCodec(self.codec.mav.srcSystem, self.codec.mav.srcComponent)

    def _on_data(self, data: bytes, now: float) -> None:
        for msg in self.codec.feed(data):
            try:
                self._on_message(msg, now)
            except Exception:  # one odd message must not kill the link thread
                log.exception("could not handle MAVLink %s", msg.get_type())

    def _housekeeping(self, now: float) -> None:
        if not self.link.is_open:
            return
        if now - self._last_gcs_heartbeat >= GCS_HEARTBEAT_S:
            self._last_gcs_heartbeat = now
            self.send(
                "heartbeat",
                mavlink.MAV_TYPE_GCS,
                mavlink.MAV_AUTOPILOT_INVALID,
                0,
                0,
                mavlink.MAV_STATE_ACTIVE,
            )
        if self._connected.is_set():
            if now - self._last_vehicle_heartbeat > self.heartbeat_timeout_s:
                log.warning(
                    "no HEARTBEAT from the vehicle for %.1f s: link lost", self.heartbeat_timeout_s
                )
                self.stats["link_lost"] += 1
                self._set_disconnected()
            elif now - self._last_link_stats >= 1.0:
                self._last_link_stats = now
                self._emit_platform("FlightTelemetryStats", self._link_stats("Connected"))

    def _link_stats(self, status: str) -> dict:
        s = self.codec.stats
        return {
            "Status": status,
            "RxFailures": s.bad_crc + s.bad_data,
            "RxUnknown": s.unknown,
            "RxMessages": s.messages,
        }

    def send(self, name: str, *args: Any, **kwargs: Any) -> None:
        """Encode one message (`send("mission_count", sys, comp, 3)`) and write it."""
        self.link.write(self.codec.encode(name, *args, **kwargs))

    def _on_message(self, msg: Any, now: float) -> None:
        kind = msg.get_type()
        source = msg.get_srcSystem()
        if kind == "HEARTBEAT" and not self._is_vehicle(msg):
            return  # another ground station, a camera, a gimbal
        if self.target_system and source != self.target_system:
            self.stats["foreign"] += 1
            return
        fields = message_fields(msg)
        with self._values_lock:
            self._latest[kind] = fields
        # State first: whoever waits for "connected" then finds the mode already known.
        self._update_state(kind, msg, now)
        if kind == "HEARTBEAT":
            self._on_heartbeat(msg, now)
        if self._listeners and kind not in NOT_TELEMETRY:
            self._queue_event(kind, fields)
        # Platform objects are kept even without listeners: objrequest answers from them.
        for name, values in self._platform_objects(kind, msg):
            self._emit_platform(name, values)
        if kind == "COMMAND_ACK":
            self._resolve_ack(msg)
        elif kind == "STATUSTEXT":
            self._on_statustext(msg, now)
        self._resolve_message(kind, msg)
        for handler in list(self._handlers):
            try:
                handler(msg)
            except Exception:
                self.stats["handler_errors"] += 1
                log.exception("MAVLink message handler failed on %s", kind)

    def _is_vehicle(self, msg: Any) -> bool:
        """The flight controller's HEARTBEAT: an autopilot that is not a peripheral on its
        bus (a Remote ID module, for one, beats as type ODID with autopilot ArduPilot and
        nothing armed), and, once one is found, that same system and component."""
        if msg.type in PERIPHERAL_TYPES or msg.autopilot == mavlink.MAV_AUTOPILOT_INVALID:
            return False
        found = (self.target_system, self.target_component)
        return not self.target_system or (msg.get_srcSystem(), msg.get_srcComponent()) == found

    def _on_heartbeat(self, msg: Any, now: float) -> None:
        self._last_vehicle_heartbeat = now
        if not self.target_system:
            self.target_system = msg.get_srcSystem()
            self.target_component = msg.get_srcComponent()
            self.autopilot = msg.autopilot
        if not self._connected.is_set():
            self.stats["connects"] += 1
            self._holder.update(connected=True)
            self._connected.set()
            log.info(
                "MAVLink vehicle %d/%d connected on %s",
                self.target_system,
                self.target_component,
                self.link_url,
            )
            threading.Thread(target=self._configure, name="mavlink-setup", daemon=True).start()

    def _configure(self) -> None:
        """Ask for the streams we map and for home; each vehicle session needs it again."""
        fallback: set[str] = set()
        for name, hz in self.stream_rates.items():
            msg_id = getattr(mavlink, f"MAVLINK_MSG_ID_{name}")
            interval_us = 1e6 / hz if hz > 0 else -1
            try:
                self.command_long(
                    mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, msg_id, interval_us, timeout=1.0
                )
            except (CommandRejected, CommandTimeout):
                fallback.add(name)
            except FlightControllerError:
                return  # disconnected again
        for stream, names in DATA_STREAMS.items():
            rates = [self.stream_rates[n] for n in names if n in fallback]
            if rates:
                self.stats["stream_fallbacks"] += 1
                with contextlib.suppress(LinkDown):
                    self.send(
                        "request_data_stream",
                        self.target_system,
                        self.target_component,
                        stream,
                        max(1, round(max(rates))),
                        1,
                    )
        with contextlib.suppress(FlightControllerError):
            self.request_message("HOME_POSITION", timeout=1.0)
        self._request_battery_identity()

    def _request_battery_identity(self) -> None:
        """Ask once per vehicle session which battery is fitted (a pack is swapped with the
        power off, so a new session); a flight controller without it refuses or is silent."""
        for name in BATTERY_IDENTITY:
            if getattr(mavlink, f"MAVLINK_MSG_ID_{name}", None) is None:
                continue  # not in this dialect
            with contextlib.suppress(FlightControllerError):
                self.request_message(name, timeout=1.0)
                return

    def _on_statustext(self, msg: Any, now: float) -> None:
        self.stats["statustext"] += 1
        text = msg.text if isinstance(msg.text, str) else bytes(msg.text).decode(errors="replace")
        text = text.rstrip("\0")
        self._statustexts.append((now, msg.severity, text))
        level = (
            logging.ERROR
            if msg.severity <= mavlink.MAV_SEVERITY_ERROR
            else logging.WARNING
            if msg.severity == mavlink.MAV_SEVERITY_WARNING
            else logging.INFO
        )
        log.log(level, "flight controller says: %s", text)

    def recent_statustext(self, since: float) -> list[str]:
        """STATUSTEXT lines received since a monotonic time (to explain a refusal)."""
        return [text for at, _, text in list(self._statustexts) if at >= since]

    def _set_disconnected(self) -> None:
        if self._connected.is_set():
            self._connected.clear()
        if self._holder.get().connected:
            self._holder.update(connected=False)
            if self._listeners:
                self._emit_platform("FlightTelemetryStats", self._link_stats("Disconnected"))
        with self._waiters_lock:
            acks, self._acks = self._acks, []
            msgs, self._msg_waiters = self._msg_waiters, []
        events = [w.event for w in acks] + [w.event for w in msgs]
        for event in events:
            event.set()  # the waiters see no answer and raise NotConnected

    def _resolve_ack(self, msg: Any) -> None:
        if msg.result == mavlink.MAV_RESULT_IN_PROGRESS:
            return  # a final ACK follows
        with self._waiters_lock:
            for waiter in list(self._acks):
                if waiter.command == msg.command:
                    waiter.result = msg.result
                    waiter.event.set()
                    self._acks.remove(waiter)

    def _resolve_message(self, kind: str, msg: Any) -> None:
        with self._waiters_lock:
            if not self._msg_waiters:
                return
            for waiter in list(self._msg_waiters):
                if waiter.name == kind:
                    waiter.msg = msg
                    waiter.event.set()
                    self._msg_waiters.remove(waiter)

    def _queue_event(self, name: str, fields: dict) -> None:
        try:
            self._events.put_nowait((name, time.time(), fields))
        except queue.Full:
            self.stats["listener_errors"] += 1

    def _emit_platform(self, name: str, values: dict) -> None:
        with self._values_lock:
            merged = self._platform.setdefault(name, {})
            merged.update(values)
            snapshot = dict(merged)
        if self._listeners:
            self._queue_event(name, snapshot)

    # --- state ------------------------------------------------------------------------
    def _update_state(self, kind: str, m: Any, now: float) -> None:
        changes: dict[str, Any] = {"updated_at": now}
        if kind == "HEARTBEAT":
            changes.update(
                armed=bool(m.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED),
                arming=False,
                flight_mode=mavutil.mode_string_v10(m),
            )
        elif kind == "GLOBAL_POSITION_INT":
            changes.update(lat=m.lat / 1e7, lon=m.lon / 1e7, alt=m.relative_alt / 1000.0)
        elif kind == "LOCAL_POSITION_NED":
            changes.update(ned=(m.x, m.y, m.z), velocity_ned=(m.vx, m.vy, m.vz))
        elif kind == "ATTITUDE":
            roll, pitch, yaw = (math.degrees(v) for v in (m.roll, m.pitch, m.yaw))
            w, x, y, z = euler_to_quaternion(roll, pitch, yaw)
            changes.update(roll=roll, pitch=pitch, yaw=yaw % 360.0, quaternion=(x, y, z, w))
        elif kind == "GPS_RAW_INT":
            changes.update(gps_fix=m.fix_type >= 3, satellites=int(m.satellites_visible))
        elif kind == "SYS_STATUS":
            if m.voltage_battery not in (0, 0xFFFF):
                changes["battery_voltage"] = m.voltage_battery / 1000.0
            if m.battery_remaining >= 0:
                changes["battery_remaining"] = m.battery_remaining / 100.0
        elif kind == "BATTERY_STATUS":
            if m.battery_remaining >= 0:
                changes["battery_remaining"] = m.battery_remaining / 100.0
        elif kind == "HOME_POSITION":
            changes["home"] = (m.latitude / 1e7, m.longitude / 1e7, m.altitude / 1000.0)
        elif kind in BATTERY_IDENTITY:
            changes["battery_serial"] = battery_serial(m)
        else:
            return
        self._holder.update(**changes)

    def _platform_objects(self, kind: str, m: Any) -> list[tuple[str, dict]]:
        """The platform objects (UAVObject names and fields) a MAVLink message updates."""
        convert = _PLATFORM_OBJECTS.get(kind)
        return convert(m) if convert is not None else []

    # --- commands ---------------------------------------------------------------------
    def _require_connected(self) -> None:
        if not self._connected.is_set():
            raise NotConnected(f"flight controller on {self.link_url} is not connected")

    def command_long(
        self, command: int, *params: float, timeout: float | None = None, tries: int | None = None
    ) -> int:
        """Send COMMAND_LONG and wait for its COMMAND_ACK; return MAV_RESULT_ACCEPTED or
        raise CommandRejected (the result named) / CommandTimeout / NotConnected."""
        values = [float(p) for p in params] + [0.0] * (7 - len(params))

        def send(confirmation: int) -> None:
            self.send(
                "command_long",
                self.target_system,
                self.target_component,
                command,
                confirmation,
                *values,
            )

        return self._command(command, send, timeout, tries)

    def command_int(
        self,
        command: int,
        frame: int,
        params: tuple[float, float, float, float],
        lat: float,
        lon: float,
        z: float,
        *,
        timeout: float | None = None,
    ) -> int:
        """COMMAND_INT (positions as 1e7 degrees) with the same ACK handling as command_long."""

        def send(confirmation: int) -> None:
            self.send(
                "command_int",
                self.target_system,
                self.target_component,
                frame,
                command,
                0,
                0,
                *params,
                round(lat * 1e7),
                round(lon * 1e7),
                z,
            )

        return self._command(command, send, timeout, None)

    def _command(
        self,
        command: int,
        send: Callable[[int], None],
        timeout: float | None,
        tries: int | None,
    ) -> int:
        self._require_connected()
        timeout = self.ack_timeout_s if timeout is None else timeout
        tries = max(1, self.command_tries if tries is None else tries)
        sent_at = time.monotonic()
        with self._command_lock:  # one command in flight: ACKs name only the command
            self.stats["commands"] += 1
            waiter = _AckWaiter(command)
            deadline = sent_at + timeout
            for confirmation in range(tries):
                with self._waiters_lock:
                    waiter.event.clear()
                    if waiter not in self._acks:
                        self._acks.append(waiter)
                try:
                    send(confirmation)
                except LinkDown as exc:
                    raise NotConnected(str(exc)) from exc
                left = min(timeout / tries, deadline - time.monotonic())
                if waiter.event.wait(max(left, 0.0)) and waiter.result is not None:
                    break
                self._require_connected()
            else:
                with self._waiters_lock:
                    if waiter in self._acks:
                        self._acks.remove(waiter)
                self.stats["command_timeouts"] += 1
                raise CommandTimeout(
                    f"No COMMAND_ACK for {command_name(command)} within {timeout:.1f} s "
                    f"({tries} tries); the flight controller did not answer"
                )
        if waiter.result != mavlink.MAV_RESULT_ACCEPTED:
            self.stats["commands_refused"] += 1
            detail = "; ".join(self.recent_statustext(sent_at))
            raise CommandRejected(command, int(waiter.result), detail)
        return int(waiter.result)

    def request_message(self, name: str, timeout: float = 2.0) -> dict:
        """MAV_CMD_REQUEST_MESSAGE for one message; wait for it and return its fields."""
        self._require_connected()
        msg_id = getattr(mavlink, f"MAVLINK_MSG_ID_{name}", None)
        if msg_id is None:
            raise FlightControllerError(f"{name} is not a MAVLink message")
        waiter = _MessageWaiter(name)
        with self._waiters_lock:
            self._msg_waiters.append(waiter)
        try:
            self.command_long(mavlink.MAV_CMD_REQUEST_MESSAGE, msg_id, timeout=timeout, tries=2)
            if not waiter.event.wait(timeout) or waiter.msg is None:
                self._require_connected()
                raise CommandTimeout(f"{name} did not arrive within {timeout:.1f} s")
        finally:
            with self._waiters_lock:
                if waiter in self._msg_waiters:
                    self._msg_waiters.remove(waiter)
        return message_fields(waiter.msg)

    def latest(self, name: str) -> dict | None:
        """Last fields of a MAVLink message or platform object, if any arrived."""
        with self._values_lock:
            values = self._latest.get(name) or self._platform.get(name)
            return dict(values) if values is not None else None

    def request_object(self, name: str, timeout: float = 2.0) -> dict:
        """`objrequest`: a MAVLink message name (ATTITUDE) or a platform object name
        (AttitudeActual); fresh by REQUEST_MESSAGE, or the last streamed copy."""
        sources = PLATFORM_SOURCES.get(name, (name,))
        is_message = hasattr(mavlink, f"MAVLINK_MSG_ID_{name}")
        if name not in PLATFORM_SOURCES and not is_message:
            raise FlightControllerError(f"{name} is neither a MAVLink message nor a mapped object")
        try:
            fields = self.request_message(sources[0], timeout=timeout)
        except FlightControllerError:
            fields = None
        if is_message and fields is not None:
            return fields
        cached = self.latest(name)
        if cached is None:
            raise FlightControllerError(f"the flight controller has not sent {name}")
        return cached

    def write_object(self, name: str, fields: dict, timeout: float = 2.0) -> None:
        """MAVLink has no writable objects; `PARAMS` writes parameters by PARAM_SET."""
        if name not in ("PARAMS", "PARAM_VALUE"):
            raise FlightControllerError(
                f"{name} cannot be written over MAVLink; write PARAMS with parameter values"
            )
        for param, value in fields.items():
            self.set_param(param, float(value), timeout=timeout)

    def set_param(self, name: str, value: float, timeout: float = 2.0) -> float:
        """PARAM_SET, confirmed by the PARAM_VALUE echo; returns the value the FC holds."""
        self._require_connected()
        if len(name) > 16:
            raise FlightControllerError(f"parameter names have at most 16 characters: {name!r}")
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            waiter = _MessageWaiter("PARAM_VALUE")
            with self._waiters_lock:
                self._msg_waiters.append(waiter)
            self.send(
                "param_set",
                self.target_system,
                self.target_component,
                name.encode(),
                value,
                mavlink.MAV_PARAM_TYPE_REAL32,
            )
            got = waiter.event.wait(min(0.5, max(deadline - time.monotonic(), 0.0)))
            with self._waiters_lock:
                if waiter in self._msg_waiters:
                    self._msg_waiters.remove(waiter)
            if got and waiter.msg is not None and _param_id(waiter.msg) == name:
                return float(waiter.msg.param_value)
            self._require_connected()
        raise CommandTimeout(f"PARAM_SET {name} was not confirmed within {timeout:.1f} s")

    @property
    def is_px4(self) -> bool:
        return self.autopilot == mavlink.MAV_AUTOPILOT_PX4

    @property
    def guided_mode(self) -> str:
        """The mode that flies to commanded positions: GUIDED, or PX4's hold (LOITER)."""
        return PX4_NAMES["GUIDED"] if self.is_px4 else "GUIDED"

    def set_mode(self, mode: str, timeout: float | None = None) -> None:
        """MAV_CMD_DO_SET_MODE: an ArduCopter custom mode (GUIDED, AUTO, LAND, ...), or on
        PX4 its main/sub mode (GUIDED → LOITER, AUTO → MISSION; PX4 names work too)."""
        if self.is_px4:
            name = PX4_NAMES.get(mode, mode)
            entry = mavutil.px4_map.get(name)
            if entry is None:
                raise FlightControllerError(f"unknown PX4 flight mode {mode!r}")
            _, main, sub = entry
            self.command_long(
                mavlink.MAV_CMD_DO_SET_MODE,
                mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
                main,
                sub,
                timeout=timeout,
            )
            self._holder.update(flight_mode=name)
            return
        number = COPTER_MODES.get(mode)
        if number is None:
            raise FlightControllerError(f"unknown flight mode {mode!r}")
        self.command_long(
            mavlink.MAV_CMD_DO_SET_MODE,
            mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
            number,
            timeout=timeout,
        )
        self._holder.update(flight_mode=mode)

    def arm(self, timeout: float = 10.0) -> None:
        self._arming(True, timeout, force=False)

    def disarm(self, timeout: float = 10.0, *, force: bool | None = None) -> None:
        """Disarm; `force` defaults to "airborne", because the agent's controller only
        lets an airborne disarm through when the ground sent force."""
        if force is None:
            force = self.state.airborne
        self._arming(False, timeout, force=force)

    def _arming(self, arm: bool, timeout: float, *, force: bool) -> None:
        self._require_connected()
        if self.state.armed == arm:
            return
        began = time.monotonic()
        if arm and not self.is_px4 and self.state.flight_mode in NOT_ARMABLE_MODES:
            # ArduCopter refuses to arm in LAND, RTL and AUTO (the mode after a landing).
            self.set_mode("GUIDED", timeout=min(timeout, self.ack_timeout_s))
        self.command_long(
            mavlink.MAV_CMD_COMPONENT_ARM_DISARM,
            1.0 if arm else 0.0,
            FORCE_MAGIC if force else 0.0,
            timeout=min(timeout, self.ack_timeout_s),
        )
        # ACCEPTED; the next HEARTBEAT carries the new state.
        word = "arm" if arm else "disarm"
        deadline = began + timeout
        while time.monotonic() < deadline:
            if self.state.armed == arm:
                log.info("flight controller %sed", word)
                return
            self._require_connected()
            if self._stop.wait(0.02):
                break
        raise CommandTimeout(f"the flight controller accepted {word} but did not {word}")

    def _ensure_guided(self) -> None:
        if self.state.flight_mode != self.guided_mode:
            self.set_mode("GUIDED")

    def takeoff(self, altitude: float) -> None:
        if altitude <= 0:
            raise FlightControllerError("take-off altitude must be above home")
        state = self.state
        if state.airborne:
            # NAV_TAKEOFF is refused in the air: climb or descend to the altitude instead.
            north, east, _ = state.ned or (0.0, 0.0, 0.0)
            self.goto_ned(north, east, -altitude)
            return
        if self.is_px4:
            # PX4 takes off from any mode, to an altitude above mean sea level.
            if state.home is None:
                raise FlightControllerError("PX4 take-off needs the home position first")
            self.command_long(
                mavlink.MAV_CMD_NAV_TAKEOFF, -1, 0, 0, math.nan, math.nan, math.nan,
                state.home[2] + altitude,
            )  # fmt: skip
            return
        self._ensure_guided()
        self.command_long(mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, math.nan, 0, 0, altitude)

    def land(self) -> None:
        self.command_long(mavlink.MAV_CMD_NAV_LAND, 0, 0, 0, math.nan, 0, 0, 0)

    def goto_ned(self, north: float, east: float, down: float) -> None:
        self._require_connected()
        self._ensure_guided()
        home = self.state.home
        if self.is_px4:
            if home is None:
                raise FlightControllerError("PX4 goto needs the home position first")
            lat, lon, alt_msl = ned_to_lla(north, east, down, home)
            self.goto_global(lat, lon, alt_msl - home[2])
            return
        if self.goto_frame == "local" or home is None:
            self.send(
                "set_position_target_local_ned",
                self._boot_ms(),
                self.target_system,
                self.target_component,
                mavlink.MAV_FRAME_LOCAL_NED,
                POSITION_ONLY_MASK,
                north,
                east,
                down,
                *([0.0] * 8),
            )
            return
        lat, lon, alt_msl = ned_to_lla(north, east, down, home)
        self.goto_global(lat, lon, alt_msl - home[2])

    def goto_global(self, lat: float, lon: float, relative_alt: float) -> None:
        """SET_POSITION_TARGET_GLOBAL_INT at an altitude above home (GUIDED); on PX4,
        whose setpoints need OFFBOARD, MAV_CMD_DO_REPOSITION (acknowledged) instead."""
        self._require_connected()
        if self.is_px4:
            home = self.state.home
            if home is None:
                raise FlightControllerError("PX4 goto needs the home position first")
            # AMSL in MAV_FRAME_GLOBAL_INT: the frame every PX4 release reads for this command.
            self.command_int(
                mavlink.MAV_CMD_DO_REPOSITION,
                mavlink.MAV_FRAME_GLOBAL_INT,
                (-1.0, float(mavlink.MAV_DO_REPOSITION_FLAGS_CHANGE_MODE), 0.0, math.nan),
                lat,
                lon,
                home[2] + relative_alt,
            )
            return
        self._ensure_guided()
        self.send(
            "set_position_target_global_int",
            self._boot_ms(),
            self.target_system,
            self.target_component,
            mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
            POSITION_ONLY_MASK,
            round(lat * 1e7),
            round(lon * 1e7),
            relative_alt,
            *([0.0] * 8),
        )

    def point_at(self, roi: tuple[float, float] | None) -> None:
        """Face a region of interest (lat, lon) while flying, or stop facing one (None).

        MAV_CMD_DO_SET_ROI_LOCATION goes as COMMAND_INT, the form both autopilots take a
        location in (ArduPilot warns about locations in COMMAND_LONG), at ground level:
        above home on ArduPilot, AMSL on PX4. MAV_CMD_DO_SET_ROI_NONE carries nothing, so
        COMMAND_LONG. Both point the nose (and a gimbal, if one is set up) at the location
        in the autopilot's own guided and mission flight.
        """
        if roi is None:
            self.command_long(mavlink.MAV_CMD_DO_SET_ROI_NONE)
            return
        lat, lon = roi
        home = self.state.home
        if self.is_px4:
            if home is None:
                raise FlightControllerError("PX4 needs the home position to place a ROI")
            frame, alt = mavlink.MAV_FRAME_GLOBAL_INT, home[2]
        else:
            frame, alt = mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, 0.0
        self.command_int(
            mavlink.MAV_CMD_DO_SET_ROI_LOCATION, frame, (0.0, 0.0, 0.0, 0.0), lat, lon, alt
        )

    def _boot_ms(self) -> int:
        return int(time.monotonic() * 1000) & 0xFFFFFFFF

    def reset(self) -> None:
        """`resetfc`: MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN (param1 1 = reboot the autopilot)."""
        self.command_long(mavlink.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN, 1)
        self._set_disconnected()
        self._holder.update(armed=False, arming=False)


def _param_id(msg: Any) -> str:
    value = msg.param_id
    if isinstance(value, bytes | bytearray):
        value = bytes(value).decode(errors="replace")
    return str(value).rstrip("\0")


def _flight_status(m: Any) -> list[tuple[str, dict]]:
    armed = bool(m.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
    return [
        (
            "FlightStatus",
            {
                "Armed": "Armed" if armed else "Disarmed",
                "FlightMode": mavutil.mode_string_v10(m),
            },
        )
    ]


def _attitude(m: Any) -> list[tuple[str, dict]]:
    roll, pitch, yaw = (math.degrees(v) for v in (m.roll, m.pitch, m.yaw))
    w, x, y, z = euler_to_quaternion(roll, pitch, yaw)
    return [
        (
            "AttitudeActual",
            {"Roll": roll, "Pitch": pitch, "Yaw": yaw, "q1": w, "q2": x, "q3": y, "q4": z},
        )
    ]


def _local_position(m: Any) -> list[tuple[str, dict]]:
    return [
        ("PositionActual", {"North": m.x, "East": m.y, "Down": m.z}),
        ("VelocityActual", {"North": m.vx, "East": m.vy, "Down": m.vz}),
    ]


def _global_position(m: Any) -> list[tuple[str, dict]]:
    return [
        (
            "GPSPosition",
            {
                "Latitude": m.lat,
                "Longitude": m.lon,
                "Altitude": m.alt / 1000.0,
                "Heading": m.hdg / 100.0 if m.hdg != 0xFFFF else None,
                "Groundspeed": math.hypot(m.vx, m.vy) / 100.0,
            },
        )
    ]


def _gps_fix(m: Any) -> list[tuple[str, dict]]:
    status = {0: "NoGPS", 1: "NoFix", 2: "Fix2D"}.get(m.fix_type, "Fix3D")
    return [
        (
            "GPSPosition",
            {
                "Status": status,
                "Satellites": m.satellites_visible,
                "HDOP": m.eph / 100.0 if m.eph != 0xFFFF else None,
                "VDOP": m.epv / 100.0 if m.epv != 0xFFFF else None,
            },
        )
    ]


def _system_status(m: Any) -> list[tuple[str, dict]]:
    battery: dict[str, Any] = {}
    if m.voltage_battery not in (0, 0xFFFF):
        battery["Voltage"] = m.voltage_battery / 1000.0
    if m.current_battery >= 0:
        battery["Current"] = m.current_battery / 100.0
    if m.battery_remaining >= 0:
        battery["Remaining"] = m.battery_remaining / 100.0
    return [
        ("FlightBatteryState", battery),
        ("SystemStats", {"CPULoad": m.load / 10.0, "RxErrors": m.errors_comm}),
    ]


def _battery_status(m: Any) -> list[tuple[str, dict]]:
    cells = [v for v in m.voltages if v not in (0xFFFF, 0)]
    values: dict[str, Any] = {"ConsumedEnergy": float(m.current_consumed)}
    if cells:
        values["Voltage"] = sum(cells) / 1000.0
        values["DetectedCellCount"] = len(cells)
    if m.current_battery >= 0:
        values["Current"] = m.current_battery / 100.0
    return [("FlightBatteryState", values)]


def _sensors(m: Any) -> list[tuple[str, dict]]:
    return [
        ("Accels", {"x": m.xacc, "y": m.yacc, "z": m.zacc, "temperature": m.temperature}),
        (
            "Gyros",
            {
                "x": math.degrees(m.xgyro),
                "y": math.degrees(m.ygyro),
                "z": math.degrees(m.zgyro),
                "temperature": m.temperature,
            },
        ),
        ("Magnetometer", {"x": m.xmag * 1000, "y": m.ymag * 1000, "z": m.zmag * 1000}),
        (
            "BaroAltitude",
            {
                "Altitude": m.pressure_alt,
                "Pressure": m.abs_pressure / 10.0,
                "Temperature": m.temperature,
            },
        ),
    ]


def _home_location(m: Any) -> list[tuple[str, dict]]:
    return [
        (
            "HomeLocation",
            {
                "Latitude": m.latitude,
                "Longitude": m.longitude,
                "Altitude": m.altitude / 1000.0,
                "Set": "TRUE",
            },
        )
    ]


def _wind_cov(m: Any) -> list[tuple[str, dict]]:
    """PX4's estimate: wind_x/y/z are the air's velocity North, East, Down, NaN when
    unknown [MAVLink WIND_COV]."""
    values = (m.wind_x, m.wind_y, m.wind_z)
    if not all(math.isfinite(v) for v in values[:2]):
        return []
    down = values[2] if math.isfinite(values[2]) else 0.0
    return [
        (
            "WindVelocityActual",
            {"North": values[0], "East": values[1], "Down": down, "Source": "WIND_COV"},
        )
    ]


def _wind(m: Any) -> list[tuple[str, dict]]:
    """ArduPilot's estimate: `direction` the wind comes from (degrees), `speed` in the
    ground plane, `speed_z` vertical [MAVLink ardupilotmega, WIND]; the air moves the other
    way."""
    if not all(math.isfinite(v) for v in (m.direction, m.speed, m.speed_z)):
        return []
    towards = math.radians(m.direction + 180.0)
    north, east = m.speed * math.cos(towards), m.speed * math.sin(towards)
    return [
        (
            "WindVelocityActual",
            {"North": north, "East": east, "Down": m.speed_z, "Source": "WIND"},
        )
    ]


# MAVLink message -> the platform objects it updates.
_PLATFORM_OBJECTS: dict[str, Callable[[Any], list[tuple[str, dict]]]] = {
    "HEARTBEAT": _flight_status,
    "ATTITUDE": _attitude,
    "LOCAL_POSITION_NED": _local_position,
    "GLOBAL_POSITION_INT": _global_position,
    "GPS_RAW_INT": _gps_fix,
    "SYS_STATUS": _system_status,
    "BATTERY_STATUS": _battery_status,
    "HIGHRES_IMU": _sensors,
    "HOME_POSITION": _home_location,
    "WIND_COV": _wind_cov,
    "WIND": _wind,
}
