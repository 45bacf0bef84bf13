"""Lightweight load drones: hundreds of protocol-correct drones in one process, no simulator.

Each load drone is its own MQTT 3.1.1 client (client id = drone id, clean_session=False,
its own credentials) that subscribes `<id>/+/in`, sends heartbeats (docs/protocol.md, every 5 s)
and telemetry (10 Hz, the send time in `ts` so the ground's lag can be measured), answers
control commands and gear queries as the real agent does, and flies missions fast-forwarded
(step progress as the real mission worker sends it). It fails over between broker nodes.

Why not the real agent: one agent plus one simulator per drone costs two processes and
~60 MB; a load drone costs a socket and a few kilobytes, so one machine hosts 1 000.

Position: a load drone on the ground drifts on a 20 m circle around its flight position,
one turn per hour. The drift is a known function of time, so whoever sees a reported
position (the fleet map) can tell how old it is: `position_age(home, lat, lon, now)`.

    python -m firmware.loaddrone --fleet fleet.json [--rate 10] [--heartbeat 5] [--duration S]
        [--per-message N]   (N samples per telemetry message: a period of N / rate s)

`fleet.json` is a list of `{"drone_id", "password", "urls": ["mqtt://host:port", ...]}`.
The process prints one JSON stats line per `--stats-interval` and a final one on exit.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import logging
import math
import signal
import struct
import sys
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any
from urllib.parse import urlsplit

from onboard import protocol
from onboard.mission import decode_mission
from onboard.navigation import lla_to_ned, ned_to_lla
from runtime.mqttwire import (
    MqttError,
    connect_packet,
    publish_packet,
    split_packets,
    subscribe_packet,
)
from runtime.retry import Backoff

log = logging.getLogger(__name__)

DEFAULT_HOME = (40.6303, -8.6575, 12.0)
DRIFT_RADIUS_M = 20.0
DRIFT_PERIOD_S = 3600.0
SPEED_M_S = 5.0  # horizontal, for fast-forwarded travel times
CLIMB_M_S = 2.0
MAX_INFLIGHT = 2000  # unacknowledged QoS 1 messages kept per drone for a resend
KEEPALIVE_S = 30
SPECS = {"TYPE": "QUADCOPTER", "FRAME_SIZE": "450", "BATTERY": {"CELL_COUNT": 4, "CAPACITY": 5000}}
SENSORS = {"GAS": {"CO2": "Load CO2"}}
OBJECTS = {
    "AttitudeActual": ("Roll", "Pitch", "Yaw"),
    "FlightBatteryState": ("Voltage", "Current"),
}


# ---------------------------------------------------------------------------------------
# Where a load drone says it is.


def drift_offset(t: float) -> tuple[float, float]:
    """(north, east) metres of the ground drift at wall time t."""
    angle = 2 * math.pi * (t % DRIFT_PERIOD_S) / DRIFT_PERIOD_S
    return DRIFT_RADIUS_M * math.cos(angle), DRIFT_RADIUS_M * math.sin(angle)


def position_age(
    home: tuple[float, float, float], lat: float, lon: float, now: float
) -> float | None:
    """How long ago a drone resting at home reported (lat, lon), from its drift circle;
    None when the position is not on the circle (the drone has flown somewhere)."""
    north, east, _down = lla_to_ned(lat, lon, home[2], home)
    if abs(math.hypot(north, east) - DRIFT_RADIUS_M) > 0.05:
        return None
    phase = (math.atan2(east, north) / (2 * math.pi)) % 1.0 * DRIFT_PERIOD_S
    return (now - phase) % DRIFT_PERIOD_S


# ---------------------------------------------------------------------------------------
# One drone's behaviour: protocol in, protocol out, no sockets.

Send = Callable[[str, bytes], object]  # (channel, payload) → published on <id>/<channel>/out


@dataclass
class Stats:
    """What a fleet process did; summed over drones, printed as JSON."""

    telemetry_messages: int = 0
    telemetry_objects: int = 0
    telemetry_unsent: int = 0  # ticks while disconnected (QoS 0: not queued, as on a drone)
    telemetry_throttled: int = 0  # ticks skipped while the broker pushed back (TCP full)
    heartbeats: int = 0
    replies: int = 0
    refused: int = 0
    missions_completed: int = 0
    steps_completed: int = 0
    connects: int = 0
    connect_failures: int = 0
    resent: int = 0
    ticks: int = 0  # scheduled slices run, for reading late_ticks as a share
    dropped: Counter = field(default_factory=Counter)

    def to_dict(self) -> dict:
        data = {k: v for k, v in self.__dict__.items() if k != "dropped"}
        data["dropped"] = dict(self.dropped)
        return data


class LoadDrone:
    """A drone's state machine: arm, fly (fast-forwarded), answer, run missions."""

    def __init__(
        self,
        drone_id: str,
        send: Send,
        stats: Stats,
        *,
        home: tuple[float, float, float] = DEFAULT_HOME,
        time_scale: float = 10.0,
    ) -> None:
        self.drone_id = drone_id
        self.send = send
        self.stats = stats
        self.home = home
        self.time_scale = time_scale
        self.armed = False
        self.airborne = False
        self.ned = (0.0, 0.0, 0.0)  # where the last target puts the drone
        self.arrive_at = 0.0  # monotonic time it gets there
        self.battery = 0.97
        self.mission: asyncio.Task | None = None
        self.mission_ref: protocol.MissionRef | None = None
        self._mission_stop: asyncio.Event | None = None
        self._mission_request_id: str | None = None

    # -- what it says ---------------------------------------------------------------------

    def position(self, t: float) -> protocol.Position:
        north, east, down = self.ned
        if not self.airborne:
            drift_n, drift_e = drift_offset(t)
            north, east = north + drift_n, east + drift_e
        lat, lon, alt_msl = ned_to_lla(north, east, down, self.home)
        return protocol.Position(lat, lon, alt_msl - self.home[2])

    def heartbeat(self) -> bytes:
        t = time.time()
        return protocol.encode(
            protocol.Heartbeat(
                drone_id=self.drone_id,
                ts=t,
                position=self.position(t),
                battery_voltage=round(12.6 + 4.2 * self.battery, 2),
                battery_remaining=self.battery,
                armed=self.armed,
                airborne=self.airborne,
                flight_mode="POSITIONHOLD" if self.airborne else "STABILIZED1",
                mission=self.mission_ref,
                fc_protocol="load",
                fc_connected=True,
            )
        )

    def telemetry(self, t: float, seq: int) -> bytes:
        return telemetry_message(t, [self.telemetry_object(t, seq)])

    def telemetry_object(self, t: float, seq: int) -> str:
        """One AttitudeActual sample as the JSON of a telemetry object."""
        # Formatted by hand: json.dumps would cost more than the rest of a tick.
        yaw = (seq * 0.7) % 360.0
        return (
            f'{{"name":"AttitudeActual","ts":{t:.6f},'
            f'"fields":{{"Roll":{math.sin(seq * 0.1):.2f},"Pitch":{math.cos(seq * 0.1):.2f},'
            f'"Yaw":{yaw:.2f}}}}}'
        )

    def gear_announcement(self) -> bytes:
        return protocol.encode(protocol.GearAnnouncement(SPECS, SENSORS))

    # -- what it hears --------------------------------------------------------------------

    def receive(self, topic: str, payload: bytes) -> None:
        """One `<id>/<channel>/in` message; bad input is answered or counted, never raised."""
        try:
            drone_id, channel, direction = protocol.split_topic(topic)
        except protocol.ProtocolError:
            self.stats.dropped["topic"] += 1
            return
        if drone_id != self.drone_id or direction != "in":
            self.stats.dropped["topic"] += 1
            return
        try:
            obj = protocol.decode_json(payload)
        except protocol.ProtocolError:
            self.stats.dropped["json"] += 1
            return
        if channel == "control":
            self._control(obj)
        elif channel == "gear":
            self._gear(obj)
        else:
            self._mission(obj)

    def _reply(self, response: protocol.ControlResponse) -> None:
        self.stats.replies += 1
        if not response.ok:
            self.stats.refused += 1
        self.send("control", protocol.encode(response))

    def _control(self, obj: Any) -> None:
        try:
            request = protocol.parse_control_request(obj)
        except protocol.ProtocolError as exc:
            request_id = protocol.request_id_of(obj)
            self.stats.dropped["control_refused" if request_id else "control"] += 1
            if request_id is not None:
                command = obj.get("command")
                command = command if isinstance(command, str) and command else "unknown"
                self._reply(
                    protocol.ControlResponse(request_id, command, False, None, _sentence(exc))
                )
            return
        try:
            result = self.execute(request.command, request.params)
        except CommandRefused as exc:
            self._reply(
                protocol.ControlResponse(request.request_id, request.command, False, None, str(exc))
            )
            return
        self._reply(protocol.ControlResponse(request.request_id, request.command, True, result))

    def _gear(self, obj: Any) -> None:
        try:
            query = protocol.parse_gear_query(obj)
        except protocol.ProtocolError as exc:
            request_id = protocol.request_id_of(obj)
            self.stats.dropped["gear"] += 1
            if request_id is not None:
                reply = protocol.GearReply(request_id, False, error=_sentence(exc))
                self.send("gear", protocol.encode(reply))
            return
        if query.query == "specs":
            reply = protocol.GearReply(query.request_id, True, specs=SPECS)
        elif query.query == "sensors":
            reply = protocol.GearReply(query.request_id, True, sensors=SENSORS)
        else:
            try:
                reply = protocol.GearReply(query.request_id, True, reading=self.read(query.sensor))
            except CommandRefused as exc:
                reply = protocol.GearReply(query.request_id, False, error=str(exc))
        self.send("gear", protocol.encode(reply))

    # -- commands -------------------------------------------------------------------------

    def execute(self, command: str, params: dict) -> dict:
        """Carry out a validated command at once (travel is timed by `arrive_at`)."""
        if command == "arm":
            self.armed = True
            return {"armed": True}
        if command == "disarm":
            if self.airborne and not params.get("force"):
                raise CommandRefused(
                    "The drone is airborne; land before disarming, or send force to disarm anyway."
                )
            self.armed = self.airborne = False
            return {"armed": False}
        if command in protocol.NAVIGATION_COMMANDS:
            return self._navigate(command, params)
        if command == "objrequest":
            names = OBJECTS.get(params["value"])
            if names is None:
                raise CommandRefused(f"This drone has no object named {params['value']!r}.")
            return {name: 0.0 for name in names}
        if command == "resetfc":
            if self.airborne and not params.get("force"):
                raise CommandRefused(
                    "The drone is airborne; rebooting the flight controller would drop it. "
                    "Send force to reboot anyway."
                )
            return {"reset": True}
        if command == "rebuildtelemetry":
            return {"rebuilt": True}
        raise CommandRefused(f"The command {command!r} is not supported by this drone.")

    def _navigate(self, command: str, params: dict) -> dict:
        if not self.armed:
            raise CommandRefused(f"The drone is not armed; arm it before {command}.")
        north, east, down = self.ned
        if command == "takeoff":
            down = -params["altitude"]
        elif command == "land":
            down = 0.0
        elif command == "changeN":
            north += params["value"]
        elif command == "changeE":
            east += params["value"]
        elif command == "altitude":
            down -= params["value"]
        else:
            north, east, _ = lla_to_ned(params["lat"], params["lon"], self.home[2], self.home)
            down -= params["altitude_delta"]
        horizontal = math.hypot(north - self.ned[0], east - self.ned[1])
        travel = horizontal / SPEED_M_S + abs(down - self.ned[2]) / CLIMB_M_S
        self.arrive_at = time.monotonic() + travel / self.time_scale
        self.ned = (north, east, down)
        self.airborne = down < -0.1
        return {"target": {"north": north, "east": east, "down": down}}

    def read(self, sensor: str | None) -> dict:
        if sensor != "CO2":
            raise CommandRefused(f"This drone has no sensor named {sensor!r} (it has: CO2).")
        position = self.position(time.time())
        return {
            "sensor": "CO2",
            "value": 410.0,
            "unit": "ppm",
            "model": "Load CO2",
            "position": position.to_dict(),
            "ts": time.time(),
        }

    # -- missions -------------------------------------------------------------------------

    def _mission(self, obj: Any) -> None:
        try:
            request = protocol.parse_mission_request(obj)
        except protocol.ProtocolError as exc:
            self.stats.dropped["mission"] += 1
            refusal = protocol.mission_refusal(obj, _sentence(exc))
            if refusal is not None:
                self._report(refusal)
            return
        if isinstance(request, protocol.MissionStop):
            self._stop_mission(request)
        else:
            self._start_mission(request)

    def _stop_mission(self, request: protocol.MissionStop) -> None:
        if self.mission_ref is None or self.mission_ref.mission_id != request.mission_id:
            not_running = "The mission is not running on this drone."
            self._report(protocol.mission_reply(request, "stopped", error=not_running))
        elif self._mission_stop is not None:
            self._mission_request_id = request.request_id  # the stop is what gets answered
            self._mission_stop.set()

    def _start_mission(self, request: protocol.MissionStart) -> None:
        # The same checks, and the same answers, as the agent's mission worker.
        try:
            payload, decode_ms = decode_mission(request)
        except protocol.ProtocolError as exc:
            self._report(protocol.mission_reply(request, "rejected", error=_sentence(exc)))
            return
        if self.mission is not None and not self.mission.done():
            busy = "Another mission is still running; stop it first."
            self._report(protocol.mission_reply(request, "rejected", error=busy))
            return
        self._report(protocol.mission_reply(request, "accepted", decode_ms=decode_ms))
        self._mission_stop = asyncio.Event()
        self._mission_request_id = request.request_id
        self.mission = asyncio.get_running_loop().create_task(
            self._fly(payload, self._mission_stop)
        )

    async def _fly(self, payload: protocol.MissionPayload, stop: asyncio.Event) -> None:
        try:
            for step in payload.steps:
                if stop.is_set():
                    self._end(payload, "stopped", "stopped by the ground")
                    return
                self.mission_ref = protocol.MissionRef(
                    payload.mission_id, payload.assignment_id, step.index
                )
                self._step(payload, step, "started")
                began = time.monotonic()
                try:
                    result = await self._run_step(payload, step, stop)
                except CommandRefused as exc:
                    self._step(payload, step, "failed", began=began, error=str(exc))
                    failed = f"Step {step.index} ({step.command}) failed: {exc}"
                    self._end(
                        payload, "stopped", "stopped by the ground" if stop.is_set() else failed
                    )
                    return
                self._step(payload, step, "completed", began=began, result=result)
                self.stats.steps_completed += 1
            self.stats.missions_completed += 1
            self._end(payload, "completed")
        finally:
            self.mission_ref = None

    def _end(self, payload: protocol.MissionPayload, status: str, error: str | None = None) -> None:
        """The mission's last report, naming (when stopped) the start request, or the stop
        request when the ground asked for it, as the agent's mission worker does."""
        request_id = self._mission_request_id
        self._report(protocol.mission_end(payload, status, error=error, request_id=request_id))

    async def _run_step(
        self, payload: protocol.MissionPayload, step: protocol.Step, stop: asyncio.Event
    ) -> dict:
        async def wait(seconds: float) -> None:
            try:
                await asyncio.wait_for(stop.wait(), max(0.0, seconds))
            except TimeoutError:
                return
            raise CommandRefused("the mission was stopped")

        if step.command == "sleep":
            await wait(step.params["value"] / self.time_scale)
            return {}
        if step.command == "wait_for_flight":
            await wait(self.arrive_at - time.monotonic())
            return {"target": dict(zip(("north", "east", "down"), self.ned, strict=True))}
        if step.command == "virtualalarm":
            position = self.position(time.time())
            alarm = protocol.Alarm(
                step.params["level"],
                step.params["message"] or "virtual alarm",
                position,
                payload.mission_id,
                payload.assignment_id,
                step.index,
            )
            self.send("alarms", protocol.encode(alarm))
            return {"level": step.params["level"]}
        if step.command == "sense":
            return {"sensor": step.params["sensor"], "reading": self.read(step.params["sensor"])}
        if step.command == "takepic":
            raise CommandRefused("This load drone has no camera.")
        return self.execute(step.command, step.params)

    def _step(
        self,
        payload: protocol.MissionPayload,
        step: protocol.Step,
        status: str,
        *,
        began: float | None = None,
        result: dict | None = None,
        error: str | None = None,
    ) -> None:
        # Durations in flight seconds, as the real worker reports them under a time scale.
        duration = None if began is None else (time.monotonic() - began) * self.time_scale
        position = self.position(time.time())
        self._report(
            protocol.step_progress(
                payload, step, status, position, duration_s=duration, result=result, error=error
            )
        )

    def _report(self, progress: protocol.MissionProgress | protocol.StepProgress) -> None:
        self.send("mission", protocol.encode(progress))


def telemetry_message(t: float, objects: list[str]) -> bytes:
    """A telemetry message sent at t carrying these objects (JSON texts), as the agent
    sends every object sampled in one telemetry period in one message."""
    return f'{{"ts":{t:.6f},"objects":[{",".join(objects)}]}}'.encode()


class CommandRefused(Exception):
    """A command the drone will not carry out; str() is the sentence for the reply."""


def _sentence(exc: protocol.ProtocolError) -> str:
    return f"Bad {exc.field}: {exc.message}."


# ---------------------------------------------------------------------------------------
# One drone's MQTT session over asyncio, with failover between broker nodes.


@dataclass(frozen=True)
class Account:
    drone_id: str
    password: str
    urls: tuple[str, ...]
    home: tuple[float, float, float] | None = None  # None: the fleet's home

    @classmethod
    def from_dict(cls, data: dict) -> Account:
        urls = data.get("urls") or [data["url"]]
        home = data.get("home")
        return cls(
            data["drone_id"], data["password"], tuple(urls), None if home is None else tuple(home)
        )

    def to_dict(self) -> dict:
        return {
            "drone_id": self.drone_id,
            "password": self.password,
            "urls": list(self.urls),
            "home": None if self.home is None else list(self.home),
        }


def grid_home(
    index: int, columns: int = 40, spacing_deg: float = 0.001
) -> tuple[float, float, float]:
    """Home of the index-th drone of a fleet: a grid of ~100 m cells, so a map shows them apart."""
    lat, lon, alt = DEFAULT_HOME
    return (lat + (index // columns) * spacing_deg, lon + (index % columns) * spacing_deg, alt)


def _address(url: str) -> tuple[str, int]:
    parts = urlsplit(url)
    return parts.hostname or "127.0.0.1", parts.port or 1883


class Session(asyncio.Protocol):
    """One drone's connection: keeps reconnecting (next node first) until `close()`."""

    def __init__(self, account: Account, fleet: Fleet) -> None:
        self.account = account
        self.fleet = fleet
        self.drone = LoadDrone(
            account.drone_id,
            self.publish,
            fleet.stats,
            home=account.home or fleet.home,
            time_scale=fleet.time_scale,
        )
        self.transport: asyncio.Transport | None = None
        self.online = False
        self.paused = False
        self.node = 0  # index into account.urls of the node tried next / connected
        self._buffer = bytearray()
        self._next_id = 0
        self._inflight: dict[int, tuple[str, bytes]] = {}
        self._closing = False
        self._lost = asyncio.Event()
        self._last_sent = 0.0
        self.samples: list[str] = []  # sampled this telemetry period, not sent yet

    # -- lifecycle ------------------------------------------------------------------------

    async def run(self, first_delay: float = 0.0) -> None:
        await asyncio.sleep(first_delay)
        # Jittered, so a thousand drones losing one node do not all land at once.
        backoff = Backoff(0.2, 5.0, jitter=True)
        loop = asyncio.get_running_loop()
        while not self._closing:
            host, port = _address(self.account.urls[self.node])
            self._lost.clear()
            try:
                await asyncio.wait_for(loop.create_connection(lambda: self, host, port), 10)
                await self._lost.wait()
                backoff.reset()
            except (OSError, TimeoutError):
                self.fleet.stats.connect_failures += 1
            if self._closing:
                break
            self.node = (self.node + 1) % len(self.account.urls)
            await asyncio.sleep(backoff.failed())

    def close(self) -> None:
        self._closing = True
        if self.transport is not None:
            self.transport.write(b"\xe0\x00")  # DISCONNECT
            self.transport.close()
        self._lost.set()

    # -- asyncio.Protocol -----------------------------------------------------------------

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        assert isinstance(transport, asyncio.Transport)
        self.transport = transport
        # About 5 s of telemetry may wait in this process; beyond it the drone skips.
        transport.set_write_buffer_limits(high=8192)
        self._buffer.clear()
        drone_id = self.account.drone_id
        transport.write(
            connect_packet(
                drone_id,
                drone_id,
                self.account.password,
                keepalive=KEEPALIVE_S,
                clean_session=False,
            )
        )
        self._last_sent = time.monotonic()

    def connection_lost(self, exc: Exception | None) -> None:
        self.transport = None
        self.online = False
        self.paused = False
        self._lost.set()

    # The broker reads slower than we write: asyncio pauses us at its high-water mark.
    # Telemetry is then skipped (and counted), as a drone's radio link drops QoS 0 data,
    # so "sent" only ever counts what left for the broker.
    def pause_writing(self) -> None:
        self.paused = True

    def resume_writing(self) -> None:
        self.paused = False

    @property
    def buffered(self) -> int:
        return 0 if self.transport is None else self.transport.get_write_buffer_size()

    def data_received(self, data: bytes) -> None:
        self._buffer += data
        try:
            packets, used = split_packets(self._buffer)
            del self._buffer[:used]
            for first, body in packets:
                self._packet(first, body)
        except MqttError as exc:
            self.fleet.stats.dropped["mqtt"] += 1
            log.warning("%s: %s; reconnecting", self.account.drone_id, exc)
            if self.transport is not None:
                self.transport.close()

    def _packet(self, first: int, body: bytes) -> None:
        kind = first >> 4
        if kind == 3:  # PUBLISH
            qos = (first >> 1) & 0x03
            topic_len = (body[0] << 8) | body[1]
            topic = body[2 : 2 + topic_len].decode("utf-8", "replace")
            start = 2 + topic_len
            if qos:
                self._write(b"\x40\x02" + body[start : start + 2])  # PUBACK
                start += 2
            try:
                self.drone.receive(topic, body[start:])
            except Exception:  # a behaviour bug must not take the whole fleet down
                log.exception("%s: message on %s failed", self.account.drone_id, topic)
                self.fleet.stats.dropped["crash"] += 1
        elif kind == 4:  # PUBACK
            self._inflight.pop(struct.unpack("!H", body[:2])[0], None)
        elif kind == 2:  # CONNACK
            if len(body) < 2 or body[1] != 0:
                raise MqttError(f"broker refused the connection (code {body[1] if body else '?'})")
            self._write(subscribe_packet(1, f"{self.account.drone_id}/+/in"))
        elif kind == 9:  # SUBACK
            if body[-1] == 0x80:
                raise MqttError("subscription refused")
            self._on_online()

    def _on_online(self) -> None:
        self.online = True
        self.fleet.stats.connects += 1
        # QoS 1 messages the broker never acknowledged go again (the ground dedups by id).
        for packet_id, (topic, payload) in list(self._inflight.items()):
            self.fleet.stats.resent += 1
            self._write(publish_packet(topic, payload, qos=1, packet_id=packet_id, dup=True))
        self.publish("gear", self.drone.gear_announcement())
        if self.publish("heartbeats", self.drone.heartbeat()):
            self.fleet.stats.heartbeats += 1

    # -- sending --------------------------------------------------------------------------

    def _write(self, data: bytes) -> None:
        if self.transport is not None:
            self.transport.write(data)
            self._last_sent = time.monotonic()

    def publish(self, channel: str, payload: bytes) -> bool:
        """Publish on `<id>/<channel>/out` with the contract's QoS; False if offline."""
        topic = f"{self.account.drone_id}/{channel}/out"
        qos = protocol.QOS[channel]
        if qos == 0:
            if not self.online:
                return False
            self._write(publish_packet(topic, payload))
            return True
        packet_id = self._packet_id()
        if len(self._inflight) >= MAX_INFLIGHT:
            self._inflight.pop(next(iter(self._inflight)))
            self.fleet.stats.dropped["inflight_overflow"] += 1
        self._inflight[packet_id] = (topic, payload)
        if self.online:
            self._write(publish_packet(topic, payload, qos=1, packet_id=packet_id))
        return self.online

    def _packet_id(self) -> int:
        while True:
            self._next_id = self._next_id % 65535 + 1
            if self._next_id not in self._inflight and self._next_id != 1:
                return self._next_id  # 1 is the SUBSCRIBE's

    def ping_if_idle(self, now: float) -> None:
        if self.online and now - self._last_sent > KEEPALIVE_S / 2:
            self._write(b"\xc0\x00")


# ---------------------------------------------------------------------------------------
# Many drones in one event loop, on one schedule.


class Fleet:
    """Runs load drones: telemetry at `rate` Hz and heartbeats every `heartbeat_interval`
    s per drone, spread evenly over time so the broker sees a steady stream."""

    def __init__(
        self,
        accounts: list[Account],
        *,
        rate: float = 10.0,
        heartbeat_interval: float = 5.0,
        time_scale: float = 10.0,
        home: tuple[float, float, float] = DEFAULT_HOME,
        connect_spread: float = 2.0,
        per_message: int = 1,
    ) -> None:
        self.stats = Stats()
        self.rate = rate
        # Samples (taken at `rate` Hz) per telemetry message: the agent's telemetry period
        # is per_message / rate, and each message carries every sample of its period.
        self.per_message = max(1, per_message)
        self.heartbeat_interval = heartbeat_interval
        self.time_scale = time_scale
        self.home = home
        self.connect_spread = connect_spread
        self.sessions = [Session(account, self) for account in accounts]
        self._stop = asyncio.Event()
        self._tasks: list[asyncio.Task] = []

    @property
    def online(self) -> int:
        return sum(1 for s in self.sessions if s.online)

    def snapshot(self) -> dict:
        return {
            "type": "stats",
            "ts": time.time(),
            "drones": len(self.sessions),
            "online": self.online,
            **self.stats.to_dict(),
        }

    async def start(self) -> None:
        n = max(1, len(self.sessions))
        for i, session in enumerate(self.sessions):
            delay = self.connect_spread * i / n
            self._tasks.append(asyncio.create_task(session.run(delay)))
        self._tasks.append(asyncio.create_task(self._telemetry_loop()))
        self._tasks.append(asyncio.create_task(self._heartbeat_loop()))

    async def wait_online(self, timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.online == len(self.sessions):
                return True
            await asyncio.sleep(0.05)
        return False

    async def stop(self, drain_timeout: float = 10.0) -> None:
        self._stop.set()
        # What was written must reach the broker before the sockets close, or "sent"
        # would count samples that never left this process.
        deadline = time.monotonic() + drain_timeout
        while any(s.buffered for s in self.sessions) and time.monotonic() < deadline:
            await asyncio.sleep(0.05)
        for session in self.sessions:
            session.close()
        for task in self._tasks:
            task.cancel()
        await asyncio.gather(*self._tasks, return_exceptions=True)
        for session in self.sessions:
            if session.drone.mission is not None:
                session.drone.mission.cancel()

    async def _spread(self, period: float, act: Callable[[Session, float], None]) -> None:
        """Call act(session, now) once per `period` for every session, in even slices."""
        slices = max(1, min(len(self.sessions), int(round(period / 0.02))))
        groups = [self.sessions[i::slices] for i in range(slices)]
        step = period / slices
        next_at = time.monotonic()
        k = 0
        while not self._stop.is_set():
            now = time.time()
            for session in groups[k % slices]:
                act(session, now)
            k += 1
            self.stats.ticks += 1
            next_at += step
            delay = next_at - time.monotonic()
            if delay < -period:  # far behind (an overloaded machine): skip, do not burst
                self.stats.dropped["late_ticks"] += 1
                next_at = time.monotonic()
                delay = 0.0
            await asyncio.sleep(max(0.0, delay))

    async def _telemetry_loop(self) -> None:
        seq = 0

        def tick(session: Session, now: float) -> None:
            nonlocal seq
            seq += 1
            samples = session.samples
            samples.append(session.drone.telemetry_object(now, seq))
            if len(samples) < self.per_message:
                return
            session.samples = []
            if session.paused:
                self.stats.telemetry_throttled += len(samples)
            elif session.publish("telemetry", telemetry_message(now, samples)):
                self.stats.telemetry_messages += 1
                self.stats.telemetry_objects += len(samples)
            else:
                self.stats.telemetry_unsent += len(samples)

        if self.rate > 0:
            await self._spread(1.0 / self.rate, tick)

    async def _heartbeat_loop(self) -> None:
        def beat(session: Session, now: float) -> None:
            if session.publish("heartbeats", session.drone.heartbeat()):
                self.stats.heartbeats += 1
            session.ping_if_idle(time.monotonic())

        await self._spread(self.heartbeat_interval, beat)


# ---------------------------------------------------------------------------------------
# Command line.


async def run_fleet(
    accounts: list[Account],
    *,
    rate: float,
    heartbeat_interval: float,
    time_scale: float,
    duration: float | None,
    stats_interval: float,
    out: Any = sys.stdout,
    per_message: int = 1,
    connect_spread: float = 2.0,
) -> dict:
    fleet = Fleet(
        accounts,
        rate=rate,
        heartbeat_interval=heartbeat_interval,
        time_scale=time_scale,
        per_message=per_message,
        connect_spread=connect_spread,
    )
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, stop.set)
    await fleet.start()
    deadline = None if duration is None else time.monotonic() + duration
    try:
        while not stop.is_set():
            if deadline is not None and time.monotonic() >= deadline:
                break
            try:
                await asyncio.wait_for(stop.wait(), stats_interval)
            except TimeoutError:
                pass
            out.write(json.dumps(fleet.snapshot()) + "\n")
            out.flush()
    finally:
        await fleet.stop()
    final = dict(fleet.snapshot(), type="final")
    out.write(json.dumps(final) + "\n")
    out.flush()
    return final


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="Run many lightweight load drones.")
    parser.add_argument("--fleet", required=True, help="JSON list of drone accounts")
    parser.add_argument("--rate", type=float, default=10.0, help="telemetry Hz per drone")
    parser.add_argument("--heartbeat", type=float, default=5.0, help="seconds between beats")
    parser.add_argument("--time-scale", type=float, default=10.0, help="mission fast-forward")
    parser.add_argument("--duration", type=float, default=None, help="seconds, then exit")
    parser.add_argument("--stats-interval", type=float, default=1.0)
    parser.add_argument(
        "--per-message", type=int, default=1, help="samples per telemetry message (period)"
    )
    parser.add_argument(
        "--connect-spread", type=float, default=2.0, help="seconds over which drones connect"
    )
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    with open(args.fleet) as f:
        accounts = [Account.from_dict(item) for item in json.load(f)]
    asyncio.run(
        run_fleet(
            accounts,
            rate=args.rate,
            heartbeat_interval=args.heartbeat,
            time_scale=args.time_scale,
            duration=args.duration,
            stats_interval=args.stats_interval,
            per_message=args.per_message,
            connect_spread=args.connect_spread,
        )
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
