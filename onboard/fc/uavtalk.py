"""UAVTalk driver for dRonin flight controllers (docs/uavtalk.md).

One I/O thread owns the link: it reads and decodes frames, ACKs every OBJ_ACK, runs the
telemetry handshake and keep-alive, reopens the line when it vanishes and keeps
`VehicleState` current. Any thread may request or write objects; those calls wait on the
I/O thread's replies. Listeners run on a separate dispatcher thread, so a listener that
itself writes to the flight controller cannot stall the link.

Navigation: the target is written to `PathDesired` (End = NED target; Mode Endpoint for
go-to and take-off, Land for landing) and FlightStatus.FlightMode is set to PathPlanner,
the mode in which dRonin's path follower flies PathDesired. Arming goes through an
injected arming switch (dRonin arms only from receiver input); FlightStatus.Armed is the
truth.
"""

from __future__ import annotations

import logging
import math
import queue
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from onboard.fc.base import (
    CommandTimeout,
    FlightControllerError,
    NotConnected,
)
from onboard.fc.driver import LinkDriver
from onboard.links import LinkDown, ReopeningLink
from onboard.uavtalk import (
    Codec,
    EncodeError,
    Frame,
    FrameDecoder,
    MessageType,
    ObjectRegistry,
    arming_vetoes,
    encode_frame,
    generations,
    receiver_setup,
)

log = logging.getLogger(__name__)

EARTH_RADIUS = 6_378_137.0
HANDSHAKE_RETRY_S = 0.5
KEEPALIVE_S = 2.0  # well under the 6 s USB keep-alive (docs/uavtalk.md, Connection)
SILENCE_TIMEOUT_S = 8.0  # nothing heard for this long: start the handshake again
IAP_STEPS = (1122, 2233, 3344)
# Board seconds between reset steps. The firmware takes gaps of 0.5 to 5 s as the board
# measures them, from when it reads each step: three times the least, so a step the board
# reads late, or one it reads early after a late one, still lands inside the window.
IAP_GAP_S = 1.5
NAV_MODE = "PathPlanner"
STATE_OBJECTS = ("FlightStatus", "HomeLocation", "GPSPosition", "PositionActual")
# A board answers an object it knows at once; one it does not know is NACKed or ignored.
PROBE_TIMEOUT_S = 1.0
ALARMS = "SystemAlarms"


@dataclass
class _Waiter:
    """A request or acked write waiting for its reply from the I/O thread."""

    object_id: int
    kind: str  # "object" (answer to OBJ_REQ) or "ack"
    event: threading.Event = field(default_factory=threading.Event)
    frame: Frame | None = None
    nacked: bool = False


class UAVTalkFlightController(LinkDriver):
    """FlightController over UAVTalk (see onboard.fc.base for the interface)."""

    protocol = "uavtalk"

    def __init__(
        self,
        link_url: str,
        *,
        arming_switch: Any = None,
        objects_dir: str | Path | None = None,
        time_scale: float = 1.0,
        registry: ObjectRegistry | None = None,
        keepalive_s: float = KEEPALIVE_S,
        silence_timeout_s: float = SILENCE_TIMEOUT_S,
        write_retries: int = 3,
        cruise_speed: float = 5.0,
    ) -> None:
        self.link_url = link_url
        self._init_link_driver(ReopeningLink(link_url), "uavtalk")
        self.registry = registry or ObjectRegistry.load(objects_dir, every_generation=True)
        self.codec = Codec(self.registry)
        self.decoder = FrameDecoder(self.registry)
        self.arming_switch = arming_switch
        if arming_switch is not None and hasattr(arming_switch, "attach"):
            arming_switch.attach(self)
        self.time_scale = time_scale
        self.keepalive_s = keepalive_s
        self.silence_timeout_s = silence_timeout_s
        self.write_retries = write_retries
        self.cruise_speed = cruise_speed
        self.stats.update({"acks_sent": 0, "handshakes": 0})
        self._values: dict[tuple[str, int], dict] = {}
        self._values_lock = threading.Lock()
        self._waiters: list[_Waiter] = []
        self._waiters_lock = threading.Lock()
        self._link_status = "Disconnected"  # the flight side's FlightTelemetryStats.Status
        self._last_heard = 0.0
        self._last_sent = 0.0
        self._last_handshake = 0.0
        # Set-up findings: the firmware generation's, and the receiver settings' (these
        # keep the board from arming, so `arm` answers with them at once).
        self._generation_report: tuple[str, ...] = ()
        self._unanswered: set[str] = set()  # objects the board knows in no generation here
        self._arming_blockers: tuple[str, ...] = ()

    # --- the protocol's part of the link skeleton (onboard/fc/driver.py) -----------------
    LINK_NAME = "flight controller"
    THREAD_PREFIX = "uavtalk"

    def _on_stop(self) -> None:
        if self.arming_switch is not None:
            try:
                getattr(self.arming_switch, "close", self.arming_switch.release)()
            except Exception:
                log.exception("arming switch release failed")

    @property
    def decoder_stats(self) -> dict:
        return self.decoder.stats.as_dict()

    def _link_was_up(self) -> bool:
        return self._connected.is_set() or self._link_status != "Disconnected"

    def _on_new_line(self, now: float) -> None:
        self.decoder = FrameDecoder(self.registry)
        self._last_heard = now

    def _on_data(self, data: bytes, now: float) -> None:
        self._last_heard = now
        for frame in self.decoder.feed(data):
            try:
                self._on_frame(frame, now)
            except Exception:  # never let one odd frame kill the link thread
                log.exception("could not handle frame %s", frame.name)

    def _housekeeping(self, now: float) -> None:
        if not self.link.is_open:
            return
        if now - self._last_heard > self.silence_timeout_s and self._link_status != "Disconnected":
            log.warning("nothing from the flight controller for %.0f s", self.silence_timeout_s)
            self._set_disconnected()
        if self._link_status != "Connected":
            if now - self._last_handshake >= HANDSHAKE_RETRY_S:
                self._last_handshake = now
                status = "Connected" if self._link_status == "HandshakeAck" else "HandshakeReq"
                self._send_gcs_stats(status)
        elif now - self._last_sent >= self.keepalive_s:
            self._send_gcs_stats("Connected")

    def _send_gcs_stats(self, status: str) -> None:
        obj = self.registry["GCSTelemetryStats"]
        values = obj.defaults() | {
            "Status": status,
            "RxFailures": self.decoder.stats.dropped,
        }
        self._send(self.codec.encode_object(obj.name, values))

    def _send(self, wire: bytes) -> None:
        self.link.write(wire)
        self._last_sent = time.monotonic()

    def _on_frame(self, frame: Frame, now: float) -> None:
        if frame.type in (MessageType.ACK, MessageType.NACK):
            self._resolve(frame, "ack", nacked=frame.type == MessageType.NACK)
            if frame.type == MessageType.NACK:
                self._resolve(frame, "object", nacked=True)
            return
        if frame.type == MessageType.OBJ_REQ:
            self._answer_request(frame)
            return
        if frame.obj is None:
            return
        if frame.type == MessageType.OBJ_ACK:
            self._send(self.codec.encode_reply(MessageType.ACK, frame))
            self.stats["acks_sent"] += 1
        if frame.is_metadata:
            self._resolve(frame, "object")
            return
        values = frame.fields()
        name = frame.obj.name
        with self._values_lock:
            self._values[(name, frame.instance_id or 0)] = values
        if name == "FlightTelemetryStats":
            self._on_link_status(values["Status"])
        self._update_state(name, values, now)
        self._resolve(frame, "object")
        if self._listeners:
            try:
                self._events.put_nowait((name, time.time(), values))
            except queue.Full:
                self.stats["listener_errors"] += 1

    def _answer_request(self, frame: Frame) -> None:
        # The board may ask for GCS-side objects; answer what we hold, NACK the rest.
        if frame.obj is not None and not frame.is_metadata:
            with self._values_lock:
                values = self._values.get((frame.obj.name, frame.instance_id or 0))
            if values is not None:
                self._send(self.codec.encode_object(frame.obj.name, values))
                return
        self._send(self.codec.encode_reply(MessageType.NACK, frame))

    def _on_link_status(self, status: str) -> None:
        before = self._link_status
        self._link_status = status
        if status == "HandshakeAck":
            self._send_gcs_stats("Connected")
        elif status == "Connected" and before != "Connected":
            self.stats["handshakes"] += 1
            self._holder.update(connected=True)
            self._connected.set()
            log.info("flight controller connected on %s", self.link_url)
            # On-change objects are not streamed: fetch them once per session.
            threading.Thread(target=self._fetch_state, name="uavtalk-fetch", daemon=True).start()
        elif status == "Disconnected" and before != "Disconnected":
            self._set_disconnected()

    def _fetch_state(self) -> None:
        try:
            self.detect_generation()
        except NotConnected:
            return  # the next session detects again
        for name in STATE_OBJECTS:
            try:
                self.request_object(name, timeout=1.0)
            except FlightControllerError as exc:
                log.debug("initial %s request failed: %s", name, exc)
        if self._uses_receiver_channels():
            self.check_receiver_setup()
        else:
            self._holder.update(setup=self._generation_report)

    def _uses_receiver_channels(self) -> bool:
        return getattr(self.arming_switch, "receiver_group", None) == receiver_setup.GROUP

    def detect_generation(self) -> str | None:
        """Ask the board for each generation's definition of the objects that differ
        between dRonin generations, and read and write with the generation whose
        definitions it answers (onboard.uavtalk.generations). None when it answers none:
        the set-up report then names each object with the ids expected."""
        variants = self.registry.variants
        answered = {name: self._answered(per) for name, per in variants.items()}
        fits = [
            g.key
            for g in generations.GENERATIONS
            if all(g.key in keys for keys in answered.values())
        ]
        self._unanswered = {name for name, keys in answered.items() if not keys}
        self._generation_report = tuple(self._neither(name) for name in sorted(self._unanswered))
        for problem in self._generation_report:
            log.warning("flight controller set-up: %s", problem)
        if not fits:
            return None
        if fits[0] != self.registry.generation:
            self.registry = self.registry.for_generation(fits[0])
            self.codec = Codec(self.registry)
        log.info("flight controller firmware: %s", generations.get(fits[0]).firmware)
        return fits[0]

    def _answered(self, per: dict) -> list[str]:
        keys = []
        for key, obj in per.items():
            try:
                # Asked twice: one lost frame must not pass for an unknown definition.
                self.request_object_id(obj.id, timeout=2 * PROBE_TIMEOUT_S, tries=2)
            except CommandTimeout:
                continue  # ignored: not this generation's
            except NotConnected:
                raise
            except FlightControllerError:
                continue  # NACKed: not this generation's
            keys.append(key)
        return keys

    def _neither(self, name: str) -> str:
        ids = ", ".join(
            f"{generations.get(key).firmware}: {obj.id:#010x}"
            for key, obj in self.registry.variants[name].items()
        )
        return (
            f"the flight controller answers no definition of {name} known here ({ids}): "
            "its firmware is another dRonin version; add its definitions "
            '(docs/uavtalk.md "Adding a firmware generation")'
        )

    def check_receiver_setup(self) -> tuple[str, ...]:
        """Read the board's receiver settings and say what to change before the agent can
        arm it through UAVTalkReceiver; the answer is logged and kept in `state.setup`
        (heartbeats carry it to the ground)."""
        found: list[str] = list(self._generation_report)
        blockers: list[str] = []
        for name in ("UAVTalkReceiver", receiver_setup.SETTINGS):
            if name not in self.registry or name in self._unanswered:
                continue
            try:
                values = self.request_object(name, timeout=2.0)
            except CommandTimeout:
                log.warning(
                    "the flight controller did not send %s; receiver set-up unchecked", name
                )
                return self.state.setup
            except FlightControllerError:
                found.append(self._unknown_object(name))
                continue
            if name == receiver_setup.SETTINGS:
                blockers = receiver_setup.problems(values)
                if hasattr(self.arming_switch, "configure"):
                    self.arming_switch.configure(values)
        for problem in blockers:
            log.warning("flight controller set-up: %s", problem)
        self._arming_blockers = tuple(blockers)
        self._holder.update(setup=tuple(found + blockers))
        return tuple(found + blockers)

    def _unknown_object(self, name: str) -> str:
        obj = self.registry[name]
        message = (
            f"the flight controller does not know {name} as defined here (id {obj.id:#010x}); "
            f"its firmware is not {generations.get(self.registry.generation).firmware}"
        )
        if name == receiver_setup.SETTINGS:
            message += ": check by hand that " + "; ".join(receiver_setup.by_hand())
        return message

    def arming_vetoes(self) -> list[str]:
        """Why the board will not arm now, in dRonin's terms: receiver settings that cannot
        arm, alarms that veto arming (read afresh), or no receiver at all."""
        found = list(self._arming_blockers)
        if ALARMS not in self.registry:
            return found
        try:
            alarms = self.request_object(ALARMS, timeout=PROBE_TIMEOUT_S)
        except FlightControllerError:
            return found  # not answered: the board's FlightStatus stays the judge
        names = self.registry[ALARMS].field("Alarm").element_names
        found += arming_vetoes.vetoes(alarms, names, self.cached("FlightStatus"))
        if not self._uses_receiver_channels() and arming_vetoes.no_receiver(alarms):
            found.append(arming_vetoes.no_receiver(alarms))  # type: ignore[arg-type]
        return found

    def _set_disconnected(self) -> None:
        self._link_status = "Disconnected"
        self._last_handshake = 0.0
        if self._connected.is_set():
            self._connected.clear()
        if self._holder.get().connected:
            self._holder.update(connected=False)
        with self._waiters_lock:
            waiters, self._waiters = self._waiters, []
        for waiter in waiters:
            waiter.event.set()  # wake them; they see no reply and raise NotConnected

    def _resolve(self, frame: Frame, kind: str, nacked: bool = False) -> None:
        # Metadata frames carry id + 1, and so does a waiter for metadata: compare raw ids.
        with self._waiters_lock:
            for waiter in list(self._waiters):
                if waiter.kind == kind and waiter.object_id == frame.object_id:
                    waiter.frame = frame
                    waiter.nacked = nacked
                    waiter.event.set()
                    self._waiters.remove(waiter)

    # --- state ------------------------------------------------------------------------
    def _update_state(self, name: str, v: dict, now: float) -> None:
        s = self._holder.get()
        changes: dict[str, object] = {"updated_at": now}
        if name == "FlightStatus":
            changes.update(
                armed=v["Armed"] == "Armed",
                arming=v["Armed"] == "Arming",
                flight_mode=str(v["FlightMode"]),
            )
        elif name == "HomeLocation":
            if v["Set"] == "TRUE":
                home = (v["Latitude"] / 1e7, v["Longitude"] / 1e7, float(v["Altitude"]))
                changes["home"] = home
                if s.ned is not None:
                    changes.update(_position(s.ned, home))
        elif name == "PositionActual":
            ned = (float(v["North"]), float(v["East"]), float(v["Down"]))
            changes["ned"] = ned
            if s.home is not None:
                changes.update(_position(ned, s.home))
        elif name == "VelocityActual":
            changes["velocity_ned"] = (float(v["North"]), float(v["East"]), float(v["Down"]))
        elif name == "GPSPosition":
            changes.update(
                gps_fix=v["Status"] in ("Fix3D", "Diff3D"),
                satellites=int(v["Satellites"]),
            )
            if s.ned is None and v["Status"] in ("Fix2D", "Fix3D", "Diff3D"):
                changes.update(lat=v["Latitude"] / 1e7, lon=v["Longitude"] / 1e7)
                if s.home is not None:
                    changes["alt"] = float(v["Altitude"]) - s.home[2]
        elif name == "AttitudeActual":
            changes.update(
                roll=float(v["Roll"]),
                pitch=float(v["Pitch"]),
                yaw=float(v["Yaw"]),
                # dRonin's q1 is the scalar part; the interface wants (qx, qy, qz, qw).
                quaternion=(float(v["q2"]), float(v["q3"]), float(v["q4"]), float(v["q1"])),
            )
        elif name == "FlightBatteryState":
            changes.update(
                battery_voltage=float(v["Voltage"]), battery_remaining=_battery_remaining(v)
            )
        self._holder.update(**changes)

    # --- requests and writes ----------------------------------------------------------
    def _wait(
        self, waiter: _Waiter, send: Callable[[], None], timeout: float, tries: int
    ) -> _Waiter:
        if not self._connected.is_set():
            raise NotConnected(f"flight controller on {self.link_url} is not connected")
        deadline = time.monotonic() + timeout
        per_try = timeout / max(tries, 1)
        for _ in range(max(tries, 1)):
            with self._waiters_lock:
                waiter.event.clear()
                if waiter not in self._waiters:
                    self._waiters.append(waiter)
            try:
                send()
            except LinkDown as exc:
                raise NotConnected(str(exc)) from exc
            left = min(per_try, deadline - time.monotonic())
            if waiter.event.wait(max(left, 0.0)) and waiter.frame is not None:
                return waiter
            if not self._connected.is_set():
                raise NotConnected(f"flight controller on {self.link_url} disconnected")
        with self._waiters_lock:
            if waiter in self._waiters:
                self._waiters.remove(waiter)
        raise CommandTimeout(f"no answer from the flight controller within {timeout:.1f} s")

    def request_object(self, name: str, timeout: float = 2.0, *, instance_id: int = 0) -> dict:
        obj = self._object(name)
        waiter = _Waiter(obj.id, "object")
        wire = self.codec.encode_request(name, instance_id=instance_id)
        self._wait(waiter, lambda: self._send(wire), timeout, tries=2)
        if waiter.nacked:
            raise FlightControllerError(
                f"the flight controller does not know {name} (id {obj.id:#010x}, NACK): "
                "this definition differs from its firmware's"
            )
        assert waiter.frame is not None
        return waiter.frame.fields()

    def request_object_id(self, object_id: int, timeout: float = 2.0, *, tries: int = 1) -> None:
        """Ask for an object by raw id; raise FlightControllerError on NACK (diagnostics)."""
        waiter = _Waiter(object_id, "object")
        wire = encode_frame(MessageType.OBJ_REQ, object_id)
        self._wait(waiter, lambda: self._send(wire), timeout, tries)
        if waiter.nacked:
            raise FlightControllerError(
                f"object {object_id:#010x} unknown to the flight controller (NACK)"
            )

    def cached(self, name: str, instance_id: int = 0) -> dict | None:
        """Last values received or written for an object, if any."""
        with self._values_lock:
            values = self._values.get((name, instance_id))
            return dict(values) if values is not None else None

    def write_object(
        self,
        name: str,
        fields: dict,
        timeout: float = 2.0,
        *,
        instance_id: int = 0,
        acked: bool = True,
    ) -> None:
        obj = self._object(name)
        base = self.cached(name, instance_id)
        if base is None and set(fields) != set(obj.field_names):
            try:
                base = self.request_object(name, timeout=min(timeout, 1.0), instance_id=instance_id)
            except FlightControllerError:
                base = None
        values = (base or obj.defaults()) | fields
        try:
            wire = self.codec.encode_object(name, values, instance_id=instance_id, acked=acked)
        except EncodeError as exc:
            raise FlightControllerError(str(exc)) from exc
        if not acked:
            if not self._connected.is_set():
                raise NotConnected(f"flight controller on {self.link_url} is not connected")
            try:
                self._send(wire)
            except LinkDown as exc:
                raise NotConnected(str(exc)) from exc
        else:
            waiter = _Waiter(obj.id, "ack")
            self._wait(waiter, lambda: self._send(wire), timeout, tries=self.write_retries)
            if waiter.nacked:
                # A board NACKs an acked write of an id it does not know: say so at once.
                raise FlightControllerError(
                    f"the flight controller refused the {name} write (NACK): it does not "
                    f"know {name} with id {obj.id:#010x}, so this definition differs from "
                    "its firmware's"
                )
        with self._values_lock:
            self._values[(name, instance_id)] = values

    def _object(self, name: str):
        try:
            return self.registry[name]
        except KeyError as exc:
            raise FlightControllerError(str(exc)) from None

    # --- commands ---------------------------------------------------------------------
    def arm(self, timeout: float = 10.0) -> None:
        self._switch_arming(True, timeout)

    def disarm(self, timeout: float = 10.0) -> None:
        self._switch_arming(False, timeout)

    def _switch_arming(self, arm: bool, timeout: float) -> None:
        if self.arming_switch is None:
            raise FlightControllerError(
                "dRonin cannot be armed by command: this driver has no arming switch"
            )
        if not self._connected.is_set():
            raise NotConnected(f"flight controller on {self.link_url} is not connected")
        if self.state.armed == arm and not self.state.arming:
            return
        word = "arm" if arm else "disarm"
        vetoes = self.arming_vetoes() if arm else []
        if vetoes:
            raise FlightControllerError("the board will not arm: " + "; ".join(vetoes))
        (self.arming_switch.request_arm if arm else self.arming_switch.request_disarm)()
        deadline = time.monotonic() + timeout
        try:
            while time.monotonic() < deadline:
                state = self.state
                if state.armed == arm and not state.arming:
                    log.info("flight controller %sed", word)
                    return
                if self._stop.wait(0.02):
                    break
        finally:
            self.arming_switch.release()
        raise CommandTimeout(f"the flight controller did not {word} within {timeout:.1f} s")

    def _path(self, end: tuple[float, float, float], mode: str) -> None:
        start = self.state.ned or end
        self.write_object(
            "PathDesired",
            {
                "Start": list(start),
                "End": list(end),
                "StartingVelocity": self.cruise_speed,
                "EndingVelocity": 0.0,
                "ModeParameters": 0.0,
                "Waypoint": 0,
                "Mode": mode,
            },
        )
        if self.state.flight_mode != NAV_MODE:
            self.write_object("FlightStatus", {"FlightMode": NAV_MODE})

    def goto_ned(self, north: float, east: float, down: float) -> None:
        self._path((north, east, down), "Endpoint")

    def takeoff(self, altitude: float) -> None:
        if altitude <= 0:
            raise FlightControllerError("take-off altitude must be above home")
        north, east, _ = self.state.ned or (0.0, 0.0, 0.0)
        self._path((north, east, -altitude), "Endpoint")

    def land(self) -> None:
        north, east, _ = self.state.ned or (0.0, 0.0, 0.0)
        self._path((north, east, 0.0), "Land")

    def reset(self) -> None:
        """`resetfc`: the firmware's reset sequence on FirmwareIAPObj; the board reboots."""
        gap = IAP_GAP_S / self.time_scale
        for index, command in enumerate(IAP_STEPS):
            if index:
                time.sleep(gap)
            self.write_object("FirmwareIAPObj", {"Command": command})
        # The board reboots now: a new session follows (the I/O thread handshakes again).
        self._set_disconnected()
        self._holder.update(armed=False, arming=False)


def _position(ned: tuple[float, float, float], home: tuple[float, float, float]) -> dict:
    """lat/lon/alt above home from NED and home: the exact inverse of navigation's LLA→NED."""
    home_lat, home_lon, home_alt = home
    radius = home_alt + EARTH_RADIUS
    lat = home_lat + math.degrees(ned[0] / radius)
    lon = home_lon + math.degrees(ned[1] / (radius * math.cos(math.radians(home_lat))))
    return {"lat": lat, "lon": lon, "alt": -ned[2]}


def _battery_remaining(v: dict) -> float | None:
    """Fraction of capacity left. dRonin computes EstimatedFlightTime from the capacity
    left and the average current, so capacity left = time × current."""
    consumed = float(v["ConsumedEnergy"])
    left_mah = float(v["EstimatedFlightTime"]) * float(v["AvgCurrent"]) / 3.6
    if left_mah <= 0 and consumed <= 0:
        return None
    total = left_mah + consumed
    return max(0.0, min(1.0, left_mah / total)) if total > 0 else None
