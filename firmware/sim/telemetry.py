"""The simulated board's UAVTalk side, sans-I/O: bytes in, bytes out, driven by `tick(now)`.

Behaves as a dRonin board does (docs/uavtalk.md): answers the telemetry handshake, streams
objects at their update periods in simulated time, answers OBJ_REQ (NACK when unknown),
acks OBJ_ACK writes, resends its own acked objects up to three times 250 ms apart, and
drops to Disconnected after 8 s without hearing from the ground (wall-clock seconds: the
link is real even when the physics run faster).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from firmware.sim.receiver import BoardChannels
from firmware.sim.vehicle import Vehicle, euler_to_quaternion
from onboard.arming_frames import Frames
from onboard.uavtalk import (
    ALL_INSTANCES,
    Codec,
    Frame,
    FrameDecoder,
    MessageType,
    ObjectRegistry,
    encode_frame,
    metadata_for,
    receiver_setup,
    unpack_metadata,
)

log = logging.getLogger(__name__)

LINK_TIMEOUT_S = 8.0
ACK_RETRY_S = 0.25
ACK_RETRIES = 3
RECEIVER_FRESH_S = 0.5  # UAVTalkReceiver values older than this (wall clock) count as gone
IAP_STEPS = (1122, 2233, 3344)
IAP_WINDOW_S = (0.5, 5.0)  # board seconds between reset steps (firmwareiap.c)
BOOT_TIME_S = 2.0  # board seconds of silence while rebooting
STREAMED = (
    "AttitudeActual",
    "GPSPosition",
    "PositionActual",
    "VelocityActual",
    "FlightBatteryState",
    "Accels",
    "Gyros",
    "BaroAltitude",
    "SystemStats",
    "FlightTelemetryStats",
    "PathDesired",
)


@dataclass
class _PendingAck:
    name: str
    wire: bytes
    object_id: int
    sent_at: float
    tries: int = 1


@dataclass
class SimStats:
    frames_in: int = 0
    acks_sent: int = 0
    acks_received: int = 0
    nacks_sent: int = 0
    writes: int = 0
    reboots: int = 0
    ack_give_ups: int = 0
    handshakes: int = 0


@dataclass
class BoardSession:
    vehicle: Vehicle
    registry: ObjectRegistry
    frames: Frames
    time_scale: float = 1.0
    arming_line: Path | None = None
    link_timeout_s: float = LINK_TIMEOUT_S
    on_reboot: Callable[[], None] | None = None
    stats: SimStats = field(default_factory=SimStats)
    # ManualControlSettings changes from the default set-up (Yaw Right+Throttle on the
    # arming_frames.json channels, an arming channel ready on 5): "Arming" →
    # "Switch+Throttle" plays a switch-armed board, "ChannelGroups.Throttle" → "PWM" one
    # set up wrong.
    receiver_settings: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.codec = Codec(self.registry)
        self.decoder = FrameDecoder(self.registry)
        self.values: dict[tuple[str, int], dict] = {}
        self.periods = {name: self.registry[name].flight.period_ms for name in STREAMED}
        self.meta_overrides: dict[str, bytes] = {}
        self._out = bytearray()
        self._last_real: float | None = None
        # Link figures of FlightTelemetryStats: bytes each way since the last report.
        self._rate = LinkRate()
        self._reset_link_state()
        self._receiver: list[int] | None = None
        self._receiver_at = -math.inf
        self._judged_settings: dict | None = None
        self._receiver_ok = True
        self._line_value: str | None = None
        self._iap_step = 0
        self._iap_at = 0.0
        self._booting_until = 0.0  # board time
        self._last_status: tuple | None = None
        self._home_sent: tuple | None = None
        self._init_values()

    # --- setup ------------------------------------------------------------------------
    def _reset_link_state(self) -> None:
        self.link_status = "Disconnected"
        self.last_heard = -math.inf
        self.next_due: dict[str, float] = {}
        self.pending_acks: list[_PendingAck] = []

    def _init_values(self) -> None:
        for obj in self.registry:
            if obj.name != "SharedDefs":
                self.values[(obj.name, 0)] = obj.defaults()
        desc = list(b"skyhive-sim".ljust(100, b"\0"))
        self.values[("FirmwareIAPObj", 0)].update(Description=desc, BoardType=0x7F)
        if receiver_setup.SETTINGS in self.registry:
            key = (receiver_setup.SETTINGS, 0)
            self.values[key] = apply_settings(
                receiver_setup.correct_settings(self.values[key], self.frames),
                self.receiver_settings,
            )
        self._set_home(*self.vehicle.home)

    def _set_home(self, lat: float, lon: float, alt: float) -> None:
        home = self.values[("HomeLocation", 0)]
        home.update(Latitude=round(lat * 1e7), Longitude=round(lon * 1e7), Altitude=alt, Set="TRUE")

    # --- input ------------------------------------------------------------------------
    def receive(self, data: bytes, now: float) -> None:
        """Bytes from the ground station, received at wall-clock time `now`."""
        if self.booting:
            return
        self._rate.received(len(data), now)
        for frame in self.decoder.feed(data):
            self.stats.frames_in += 1
            self.last_heard = now
            try:
                self._handle(frame, now)
            except Exception:  # a write the model cannot apply must not stop the board
                log.exception("could not apply %s", frame.name or hex(frame.object_id))

    def _handle(self, frame: Frame, now: float) -> None:
        if frame.type == MessageType.ACK:
            self._match_ack(frame.object_id)
            return
        if frame.type == MessageType.NACK:
            return
        if frame.obj is None:
            # Unknown object: NACK requests and acked writes, as the firmware does.
            if frame.type in (MessageType.OBJ_REQ, MessageType.OBJ_ACK):
                self._send(self.codec.encode_reply(MessageType.NACK, frame))
                self.stats.nacks_sent += 1
            return
        if frame.type == MessageType.OBJ_REQ:
            self._answer_request(frame)
            return
        # OBJ or OBJ_ACK: a write.
        if frame.is_metadata:
            self._apply_metadata(frame)
        else:
            self._apply_write(frame, now)
        if frame.type == MessageType.OBJ_ACK:
            self._send(self.codec.encode_reply(MessageType.ACK, frame))
            self.stats.acks_sent += 1

    def _answer_request(self, frame: Frame) -> None:
        obj = frame.obj
        assert obj is not None
        if frame.is_metadata:
            wire = self.meta_overrides.get(obj.name) or metadata_for(obj)
            self._send(encode_frame(MessageType.OBJ, obj.id + 1, wire))
            return
        self._refresh(obj.name)
        if obj.single_instance:
            instances = [0]
        elif frame.instance_id == ALL_INSTANCES:
            instances = sorted(i for (n, i) in self.values if n == obj.name)
        else:
            instances = [frame.instance_id or 0]
        sent = False
        for inst in instances:
            values = self.values.get((obj.name, inst))
            if values is not None:
                self._send(self.codec.encode_object(obj.name, values, instance_id=inst))
                sent = True
        if not sent:
            self._send(self.codec.encode_reply(MessageType.NACK, frame))
            self.stats.nacks_sent += 1

    def _apply_metadata(self, frame: Frame) -> None:
        obj = frame.obj
        assert obj is not None
        meta = unpack_metadata(frame.payload)
        self.meta_overrides[obj.name] = frame.payload
        if obj.name in self.periods:
            mode = meta["flight_update_mode"]
            self.periods[obj.name] = (
                meta["flight_period_ms"] if mode in ("periodic", "throttled") else 0
            )
            self.next_due.pop(obj.name, None)

    def _apply_write(self, frame: Frame, now: float) -> None:
        obj = frame.obj
        assert obj is not None
        values = frame.fields()
        name = obj.name
        self.stats.writes += 1
        inst = frame.instance_id or 0
        if name == "GCSTelemetryStats":
            self._handshake(values["Status"], now)
        elif name == "FlightStatus":
            # Only the mode: arming comes from the receiver, never from a write.
            self.vehicle.set_flight_mode(values["FlightMode"])
        elif name == "PathDesired":
            self.vehicle.set_path_desired(values["Mode"], values["End"])
        elif name == "Waypoint":
            self.vehicle.set_waypoint(inst, values["Mode"], values["Position"])
        elif name == "UAVTalkReceiver":
            self._receiver = list(values["Channel"])
            self._receiver_at = now
        elif name == "HomeLocation":
            if values["Set"] == "TRUE":
                self.vehicle.set_home(
                    values["Latitude"] / 1e7, values["Longitude"] / 1e7, values["Altitude"]
                )
        elif name == "FirmwareIAPObj":
            self._iap(values["Command"])
        self.values[(name, inst)] = values

    def _handshake(self, gcs_status: str, now: float) -> None:
        before = self.link_status
        if gcs_status == "HandshakeReq":
            self.link_status = "HandshakeAck"
        elif gcs_status == "Connected" and before in ("HandshakeAck", "Connected"):
            self.link_status = "Connected"
        elif gcs_status == "Disconnected":
            self.link_status = "Disconnected"
        if self.link_status != before or self.link_status != "Connected":
            # Tell a ground station that thinks it is connected that it is not, at once.
            self._send_object("FlightTelemetryStats")
        if self.link_status == "Connected" and before != "Connected":
            self.stats.handshakes += 1
            self.next_due.clear()
            self._last_status = None
            self._home_sent = None

    def _match_ack(self, object_id: int) -> None:
        for pending in self.pending_acks:
            if pending.object_id == object_id:
                self.pending_acks.remove(pending)
                self.stats.acks_received += 1
                return

    def _iap(self, command: int) -> None:
        board = self.vehicle.time
        gap = board - self._iap_at
        expected = IAP_STEPS[self._iap_step]
        in_window = self._iap_step == 0 or IAP_WINDOW_S[0] <= gap <= IAP_WINDOW_S[1]
        if command == expected and in_window:
            self._iap_step += 1
            self._iap_at = board
            if self._iap_step == len(IAP_STEPS):
                self.reboot()
        else:
            self._iap_step = 1 if command == IAP_STEPS[0] else 0
            self._iap_at = board

    def reboot(self) -> None:
        """Restart the board: link down, disarmed, home kept, silent while booting."""
        self.stats.reboots += 1
        self._iap_step = 0
        self.vehicle.reboot()
        self._booting_until = self.vehicle.time + BOOT_TIME_S
        self._reset_link_state()
        self._out.clear()
        self.decoder = FrameDecoder(self.registry)
        self._receiver = None
        if self.on_reboot is not None:
            self.on_reboot()

    @property
    def booting(self) -> bool:
        return self.vehicle.time < self._booting_until

    # --- time -------------------------------------------------------------------------
    def tick(self, now: float) -> None:
        """Advance the board to wall-clock time `now`: physics, arming input, telemetry."""
        if self._last_real is None:
            self._last_real = now
        real_dt = max(0.0, now - self._last_real)
        self._last_real = now
        sim_dt = min(real_dt * self.time_scale, 1.0)
        while sim_dt > 1e-9:  # sub-steps keep the kinematics smooth after a stall
            dt = min(sim_dt, 0.05)
            self.vehicle.feed_receiver(self._receiver_input(now))
            self.vehicle.step(dt)
            sim_dt -= dt
        if self.booting:
            return
        if self.link_status != "Disconnected" and now - self.last_heard > self.link_timeout_s:
            log.info("no data from the ground for %.0f s: Disconnected", self.link_timeout_s)
            self.link_status = "Disconnected"
            self.pending_acks.clear()
        self._resend_acked(now)
        if self.link_status == "Connected":
            self._stream()

    def _receiver_input(self, now: float) -> list[int]:
        line = self._read_arming_line()
        if line is not None and line[0] == "1":
            return self.frames.disarm_frame_us if line[1:2] == "1" else self.frames.arm_frame_us
        if (
            self._receiver is not None
            and now - self._receiver_at <= RECEIVER_FRESH_S
            and self._reads_uavtalk_receiver()
        ):
            settings = self.values.get((receiver_setup.SETTINGS, 0))
            if settings is None:  # no ManualControlSettings: read as the fixed frames
                return [c - self.frames.separator_us for c in self._receiver]
            return BoardChannels(self._receiver, settings)
        return self.frames.safe_frame_us

    def _reads_uavtalk_receiver(self) -> bool:
        """A board set up otherwise ignores UAVTalkReceiver channels, as dRonin does
        (judged again whenever ManualControlSettings is written)."""
        settings = self.values.get((receiver_setup.SETTINGS, 0))
        if settings is not self._judged_settings:
            self._judged_settings = settings
            self._receiver_ok = settings is None or not receiver_setup.problems(settings)
        return self._receiver_ok

    def _read_arming_line(self) -> str | None:
        if self.arming_line is None:
            return None
        try:
            text = self.arming_line.read_text()[:2]
        except OSError:
            return self._line_value
        # A half-written or odd file keeps the last level, as a real pin would.
        if len(text) == 2 and set(text) <= {"0", "1"}:
            self._line_value = text
        return self._line_value

    def _stream(self) -> None:
        board = self.vehicle.time
        for name, period_ms in self.periods.items():
            if period_ms <= 0:
                continue
            due = self.next_due.get(name)
            if due is None or board >= due:
                self._send_object(name)
                period = period_ms / 1000.0
                nxt = (due if due is not None else board) + period
                self.next_due[name] = nxt if nxt > board else board + period
        status = (self.vehicle.status(), self.vehicle.flight_mode)
        if status != self._last_status:
            self._last_status = status
            self._send_object("FlightStatus")
        home = tuple(self.values[("HomeLocation", 0)][k] for k in ("Latitude", "Longitude"))
        if home != self._home_sent:
            self._home_sent = home
            self._send_object("HomeLocation", acked=True)

    def _resend_acked(self, now: float) -> None:
        for pending in list(self.pending_acks):
            if now - pending.sent_at < ACK_RETRY_S:
                continue
            if pending.tries > ACK_RETRIES:
                self.pending_acks.remove(pending)
                self.stats.ack_give_ups += 1
                continue
            pending.tries += 1
            pending.sent_at = now
            self._send(pending.wire)

    # --- output -----------------------------------------------------------------------
    def _send(self, wire: bytes) -> None:
        self._out += wire
        self._rate.sent(len(wire))

    def _send_object(self, name: str, *, acked: bool = False) -> None:
        self._refresh(name)
        wire = self.codec.encode_object(name, self.values[(name, 0)], acked=acked)
        if acked:
            obj_id = self.registry[name].id
            self.pending_acks = [p for p in self.pending_acks if p.object_id != obj_id]
            self.pending_acks.append(_PendingAck(name, wire, obj_id, self._last_real or 0.0))
        self._send(wire)

    def take_output(self) -> bytes:
        """Bytes to write to the ground station since the last call."""
        out = bytes(self._out)
        self._out.clear()
        return out

    def _refresh(self, name: str) -> None:
        """Bring an object's values up to date from the vehicle model."""
        values = self.values[(name, 0)]
        self._refresh_navigation(name, values)
        self._refresh_system(name, values)

    def _refresh_navigation(self, name: str, values: dict) -> None:
        """Where the vehicle is, how it is turned and moving, and where it is going."""
        v = self.vehicle
        if name == "AttitudeActual":
            roll, pitch, yaw = v.attitude()
            q = euler_to_quaternion(roll, pitch, yaw)
            values.update(q1=q[0], q2=q[1], q3=q[2], q4=q[3], Roll=roll, Pitch=pitch, Yaw=yaw)
        elif name == "PositionActual":
            values.update(North=v.ned[0], East=v.ned[1], Down=v.ned[2])
        elif name == "VelocityActual":
            values.update(North=v.velocity[0], East=v.velocity[1], Down=v.velocity[2])
        elif name == "GPSPosition":
            lat, lon, alt = v.lla()
            values.update(
                Latitude=round(lat * 1e7),
                Longitude=round(lon * 1e7),
                Altitude=alt,
                GeoidSeparation=50.0,
                Heading=v.yaw,
                Groundspeed=math.hypot(v.velocity[0], v.velocity[1]),
                Accuracy=1.5,
                PDOP=1.4,
                HDOP=0.9,
                VDOP=1.1,
                Status="Fix3D",
                Satellites=v.config.satellites,
            )
        elif name == "PathDesired":
            values.update(
                End=list(v.target.end),
                Mode=v.target.mode
                if v.target.mode in self.registry["PathDesired"].field("Mode").options
                else "HoldPosition",
            )

    def _refresh_system(self, name: str, values: dict) -> None:
        """Flight status, battery, sensors and board statistics."""
        v = self.vehicle
        if name == "FlightStatus":
            values.update(Armed=v.status(), FlightMode=v.flight_mode, ControlSource="Transmitter")
        elif name == "FlightBatteryState":
            values.update(
                Voltage=v.voltage,
                Current=v.current_a,
                BoardSupplyVoltage=5.0,
                PeakCurrent=v.peak_current_a,
                AvgCurrent=v.current_a,
                ConsumedEnergy=v.consumed_mah,
                EstimatedFlightTime=v.estimated_flight_time(),
                DetectedCellCount=v.config.cells,
            )
        elif name == "Accels":
            values.update(x=0.0, y=0.0, z=-9.81, temperature=35.0)
        elif name == "Gyros":
            values.update(x=0.0, y=0.0, z=0.0, temperature=35.0)
        elif name == "BaroAltitude":
            alt = v.lla()[2]
            values.update(
                Altitude=alt, Temperature=15.0, Pressure=101.325 * (1 - 2.25577e-5 * alt) ** 5.25588
            )
        elif name == "SystemStats":
            values.update(
                FlightTime=int(v.time * 1000) & 0xFFFFFFFF,
                HeapRemaining=20_000,
                FastHeapRemaining=8_000,
                IRQStackRemaining=400,
                OSStackRemaining=600,
                CPULoad=20,
                CPUTemp=40,
            )
        elif name == "FlightTelemetryStats":
            rx, tx = self._rate.report()
            values.update(Status=self.link_status, RxDataRate=rx, TxDataRate=tx)


class LinkRate:
    """Bytes per second each way over the link, as the board reports them in
    FlightTelemetryStats: averaged since the previous report."""

    def __init__(self) -> None:
        self.rx = self.tx = 0
        self.since: float | None = None
        self.now: float | None = None
        self.last = (0.0, 0.0)

    def received(self, count: int, now: float) -> None:
        self.rx += count
        self.now = now
        if self.since is None:
            self.since = now

    def sent(self, count: int) -> None:
        self.tx += count

    def report(self) -> tuple[float, float]:
        if self.since is None or self.now is None or self.now - self.since < 1.0:
            return self.last
        span = self.now - self.since
        self.last = (self.rx / span, self.tx / span)
        self.rx = self.tx = 0
        self.since = self.now
        return self.last


def apply_settings(values: dict, changes: dict) -> dict:
    """Object values with `changes` applied: "Field" or "Field.Element" → value (numbers
    as text are converted to the field's type); KeyError or ValueError for an unknown
    field or element."""
    values = {k: list(v) if isinstance(v, list) else v for k, v in values.items()}
    for key, raw in changes.items():
        name, _, element = key.partition(".")
        current = values[name]
        if element:
            index = receiver_setup.ELEMENTS.index(element)
            current = current[index]
        value = type(current)(raw) if isinstance(current, int | float) else raw
        if element:
            values[name][receiver_setup.ELEMENTS.index(element)] = value
        else:
            values[name] = value
    return values
