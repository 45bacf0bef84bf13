"""The onboard agent: wires the flight controller to the broker.

Inputs arrive on `<id>/control/in`, `<id>/mission/in` and `<id>/gear/in`; everything the
drone says goes out on the `<id>/<channel>/out` topics of docs/protocol.md. Malformed input is
answered with an error when it carries a request_id, otherwise dropped and counted; no
input can stop the agent.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import Counter, deque
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from . import protocol
from .collect import Collector, GroundClient
from .controller import CommandError, Controller
from .envelope import EnvelopeGuard
from .failsafe import FailSafe, GroundClock, Limits
from .fc.base import FlightController
from .gear import GearManager
from .heartbeat import Heartbeater, build_heartbeat
from .logger import FlightLogger
from .mission import MissionWorker, position_of
from .mqtt import MqttLink, parse_broker_urls
from .navigation import NavigationProcessor, current_ned
from .remote_id import RemoteId
from .sensors import SensorField
from .traffic import TrafficError, TrafficWatch, parse_traffic
from .wind import DEFAULT_HOLD_S, WindLimitError, WindWatch, guards, limit_from_specs

log = logging.getLogger(__name__)

TELEMETRY_BATCH_MAX = 200
# Requests that make the drone do something, each acted on once per request_id.
ACT_ON = ("control", "mission")
# How many request ids the agent remembers: far more than arrive within any redelivery.
RECENT_REQUESTS = 4096
# Control commands that do not move the drone: they are not the operator taking it over.
READ_ONLY_COMMANDS = ("objrequest", "takepic", "rebuildtelemetry")


@dataclass
class AgentConfig:
    drone_id: str
    # One mqtt:// URL, or every node of a broker cluster comma-separated: the link moves
    # to the next node when its connection is lost (onboard.mqtt.attach_failover).
    broker_url: str
    gear_dir: Path | None = None
    log_dir: Path | None = None
    pictures_dir: Path | None = None
    time_scale: float = 1.0
    heartbeat_interval: float = 5.0
    telemetry_interval: float = 0.1
    battery_critical: float = Limits.battery_critical
    bounds: dict[str, tuple[float | None, float | None]] = field(default_factory=dict)
    # Fail-safe limits (onboard.failsafe.Limits): waits on the ground in wall seconds,
    # the auto-disarm delay in flight seconds.
    battery_reserve: float = Limits.battery_reserve
    alarm_repeat: float = Limits.alarm_repeat
    critical_takeover: float = Limits.critical_takeover
    link_loss_timeout: float = Limits.link_loss_timeout
    link_loss_action: str = Limits.link_loss_action
    return_speed: float = Limits.return_speed
    auto_disarm_delay: float = Limits.auto_disarm_delay
    # Requests older than this (wall seconds since the ground issued them) are refused, so
    # nothing queued while the drone was away flies later.
    max_control_age: float = 10.0
    max_mission_age: float = 60.0
    sensor_field: SensorField | None = None
    gear_reread_interval: float = 5.0
    arm_timeout: float = 20.0
    flight_timeout: float = 600.0
    camera: str = "sim"
    # Past-image view (onboard/video.py): camera frames on <id>/camera/out and Pose
    # samples on <id>/telemetry/out, per second; 0 turns each off.
    video_rate: float = 0.0
    pose_rate: float = 0.0
    # Live video to the ground's media server (onboard/live_video.py): its address (None:
    # no live video) and frames per second.
    media_url: str | None = None
    live_fps: float = 15.0
    mqtt_keepalive: int = 10
    # Behind an internal broker, the broker connection says nothing about the ground: the
    # bridge's state topic (onboard.bridge.state_topic) does.
    ground_link_topic: str | None = None
    # Where the last flight envelope received on <id>/envelope/in is kept across restarts.
    envelope_file: Path | None = None
    # Logs collected by themselves (onboard.collect): the ground's web address (None: not
    # collected), the uplink's type when the gear folder does not say, and the rates in
    # bytes per second of the upload and of the flight controller's log coming down.
    ground_url: str | None = None
    uplink: str = "unknown"
    log_upload_rate: float = 512 * 1024
    fc_log_rate: float = 32 * 1024
    # Flight seconds the wind stays above the gear's limit before the drone returns.
    wind_hold: float = DEFAULT_HOLD_S


class Agent:
    def __init__(self, config: AgentConfig, fc: FlightController) -> None:
        if not protocol.is_drone_id(config.drone_id):
            raise ValueError(f"{config.drone_id!r} is not a valid drone id")
        self.config = config
        self.drone_id = config.drone_id
        self.fc = fc
        self.dropped: Counter[str] = Counter()
        self._recent = RecentIds(RECENT_REQUESTS)
        self.sent: Counter[str] = Counter()
        self.logger = FlightLogger(config.log_dir, self.drone_id) if config.log_dir else None
        self.collector = self._collector(config, fc)
        self._armed_at: float | None = None
        self.gear = self._gear_manager(config)
        self.navigation = NavigationProcessor(fc)
        self.envelope = EnvelopeGuard(config.envelope_file)
        self.remote_id = RemoteId(fc)
        self.traffic = TrafficWatch(
            self.drone_id, lambda: self.fc.state, time_scale=config.time_scale
        )
        self.wind = WindWatch(
            self._wind_limit,
            lambda reason: self.failsafe.return_home(reason),
            hold_s=config.wind_hold,
            time_scale=config.time_scale,
        )
        self.controller = Controller(
            fc,
            self.navigation,
            gear=self.gear,
            arm_timeout=config.arm_timeout,
            events=self._event,
            guard=guards(self.envelope.refusal, self.wind.guard),
            on_arm=lambda: self.failsafe.arm_requested(),
        )
        self.worker = MissionWorker(
            fc,
            self.controller,
            self.navigation,
            lambda message: self.send("mission", message),
            raise_alarm=self.raise_alarm,
            gear=self.gear,
            on_reading=self._on_reading,
            time_scale=config.time_scale,
            flight_timeout=config.flight_timeout,
            events=self._event,
        )
        self.failsafe = self._failsafe(config)
        self.worker.on_end = self.failsafe.mission_ended
        self.controller.actions.update(hold=self._hold, **{"return": self._return})
        self.ground_clock = GroundClock()
        self.mqtt = self._mqtt_link(config)
        self.heartbeater = Heartbeater(config.heartbeat_interval, self._beat)
        self.video: Any = None
        self.live_video: Any = None
        self._control_pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="control")
        self._telemetry: list[protocol.TelemetryObject] = []
        self._telemetry_lock = threading.Lock()
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []

    def _gear_manager(self, config: AgentConfig) -> GearManager:
        """The drone's gear (sensors, camera, pictures), reread as its files change."""
        return GearManager(
            config.gear_dir,
            self.send,
            reread_interval=config.gear_reread_interval,
            sensor_field=config.sensor_field,
            pictures_dir=config.pictures_dir,
            camera=config.camera,
        )

    def _collector(self, config: AgentConfig, fc: FlightController) -> Collector | None:
        """Uploads each flight's logs after landing, signed in with the broker password;
        None without the ground's address or a log folder."""
        if config.ground_url is None or config.log_dir is None:
            return None
        password = parse_broker_urls(config.broker_url)[0].password or ""
        return Collector(
            config.log_dir / "collect",
            GroundClient(config.ground_url, self.drone_id, password),
            gear_dir=config.gear_dir,
            uplink=config.uplink,
            rate=config.log_upload_rate,
            may_send=lambda: not fc.state.armed,
            fetch=fc_log_fetch(fc, config.log_dir / "fc", config.fc_log_rate),
            policy_file=config.log_dir / "collect-policy.json",
        )

    def _failsafe(self, config: AgentConfig) -> FailSafe:
        """The fail-safes: they stop the running mission before they act."""
        return FailSafe(
            self.fc,
            self.raise_alarm,
            navigation=self.navigation,
            stop_mission=self.worker.stop_current,
            bounds=config.bounds,
            limits=failsafe_limits(config),
            time_scale=config.time_scale,
        )

    def _mqtt_link(self, config: AgentConfig) -> MqttLink:
        """The broker connection: this drone's `in` channels, and the bridge's state topic
        when behind an internal broker."""
        return MqttLink(
            config.broker_url,
            client_id=f"skyhive-agent-{self.drone_id}",
            subscriptions=[protocol.topic(self.drone_id, c, "in") for c in protocol.IN_CHANNELS]
            + ([config.ground_link_topic] if config.ground_link_topic else []),
            on_message=self._on_message,
            on_connection=self._on_connection,
            keepalive=config.mqtt_keepalive,
        )

    # -- lifecycle ------------------------------------------------------------------------

    def start(self) -> None:
        self.fc.add_listener(self._on_object)
        self.fc.add_listener(self.wind.on_object)
        self.fc.start()
        self.remote_id.start()
        self.worker.start()
        self.gear.start()
        self.mqtt.start()
        self.heartbeater.start()
        if self.collector is not None:
            self.collector.start()
        if self.config.video_rate > 0 or self.config.pose_rate > 0:
            self.video = self._video_streamer()
            self.video.start()
        if self.config.media_url:
            self.live_video = self._live_video()
            self.live_video.start()
        for target, name in ((self._telemetry_loop, "telemetry"), (self._supervise, "supervisor")):
            thread = threading.Thread(target=target, name=name, daemon=True)
            thread.start()
            self._threads.append(thread)

    def stop(self) -> None:
        """Stop cleanly: the running mission is reported stopped and the outbox flushed."""
        self.worker.close()
        self._stop.set()
        self.heartbeater.stop()
        if self.video is not None:
            self.video.stop()
        if self.live_video is not None:
            self.live_video.stop()
        self.gear.stop()
        self._control_pool.shutdown(wait=False, cancel_futures=True)
        for thread in self._threads:
            thread.join(2)
        self._flush_telemetry()
        if self.collector is not None:
            self.collector.stop()
        self.mqtt.stop(flush_timeout=3.0)
        if self.logger is not None:
            self.logger.close()
        self.remote_id.stop()
        self.fc.stop()

    # -- outgoing -------------------------------------------------------------------------

    def send(self, channel: str, message: Any) -> None:
        """Publish a message on `<id>/<channel>/out` with the contract's QoS."""
        self.mqtt.publish(
            protocol.topic(self.drone_id, channel, "out"),
            protocol.encode(message),
            qos=protocol.QOS[channel],
        )
        self.sent[channel] += 1

    def raise_alarm(
        self,
        level: str,
        message: str,
        *,
        sensor: str | None = None,
        value: float | None = None,
        context: dict | None = None,
    ) -> None:
        """Publish an alarm with the drone's position and the mission it is flying."""
        if context is None:
            ref = self.worker.current
            context = {} if ref is None else ref.to_dict()
        alarm = protocol.Alarm(
            level=level,
            message=message,
            position=position_of(self.fc.state),
            mission_id=context.get("mission_id"),
            assignment_id=context.get("assignment_id"),
            index=context.get("index"),
            sensor=sensor,
            value=value,
        )
        self.send("alarms", alarm)
        self._event(
            "alarm", {"level": level, "sensor": sensor, "value": value, "position": alarm.position}
        )

    def _beat(self) -> None:
        beat = build_heartbeat(
            self.drone_id, self.fc.state, self.worker.current, self.remote_id.health()
        )
        self.send("heartbeats", self.wind.with_report(beat))

    def _wind_limit(self) -> float:
        """The gear's wind limit (specs.json MAX_WIND_M_S), else the default."""
        try:
            return limit_from_specs(self.gear.announcement().specs)
        except WindLimitError:  # the gear manager refuses such specs; never fly unlimited
            return limit_from_specs(None)

    def _event(self, kind: str, details: dict) -> None:
        if self.logger is not None:
            self.logger.event(kind, details)

    # -- flight-controller objects --------------------------------------------------------

    def _on_object(self, name: str, ts: float, fields: dict) -> None:
        with self._telemetry_lock:
            self._telemetry.append(protocol.TelemetryObject(name, ts, fields))
        if self.logger is not None:
            self.logger.telemetry(name, ts, fields)

    def _flush_telemetry(self) -> None:
        with self._telemetry_lock:
            batch, self._telemetry = self._telemetry, []
        for start in range(0, len(batch), TELEMETRY_BATCH_MAX):
            chunk = tuple(batch[start : start + TELEMETRY_BATCH_MAX])
            self.send("telemetry", protocol.Telemetry(chunk))

    def _telemetry_loop(self) -> None:
        while not self._stop.wait(self.config.telemetry_interval):
            try:
                self._flush_telemetry()
            except Exception:
                log.exception("telemetry publish failed")

    def _video_streamer(self) -> Any:
        from .video import VideoConfig, VideoStreamer  # the `camera` extra: only when streaming

        config = VideoConfig(
            rate_hz=self.config.video_rate,
            pose_hz=self.config.pose_rate,
            time_scale=self.config.time_scale,
        )
        return VideoStreamer(lambda: self.fc.state, self.send, config, enabled=self.gear.has_camera)

    def _live_video(self) -> Any:
        """The live video publisher: a process of its own, fed the pose without blocking."""
        from urllib.parse import unquote, urlsplit

        from .live_video import LiveVideo, LiveVideoConfig  # the `camera` extra
        from .video import PoseSource, VideoConfig

        password = unquote(urlsplit(self.config.broker_url.split(",")[0]).password or "")
        config = LiveVideoConfig(
            str(self.config.media_url), self.drone_id, password, fps=self.config.live_fps
        )
        poses = PoseSource(lambda: self.fc.state, VideoConfig(time_scale=self.config.time_scale))
        return LiveVideo(
            config, poses.sample, enabled=self.gear.has_camera, uplink=self.mqtt.socket
        )

    def _supervise(self) -> None:
        while not self._stop.wait(0.2):
            try:
                self.failsafe.tick()
                self.wind.tick(self.fc.state)
                self._keep_inside()
                self._keep_apart()
                self._watch_flight(self.fc.state.armed)
            except Exception:
                log.exception("supervisor tick failed")

    def _watch_flight(self, armed: bool) -> None:
        """At a disarm the flight's recording closes and, when collecting, its logs are
        queued for the ground."""
        archive = self.logger.on_state(armed) if self.logger is not None else None
        if armed and self._armed_at is None:
            self._armed_at = time.time()
            if self.collector is not None:
                self.collector.flight_started()
        elif not armed and self._armed_at is not None:
            started, self._armed_at = self._armed_at, None
            if self.collector is not None:
                self.collector.flight_ended(archive, started, time.time())

    def _keep_inside(self) -> None:
        """Found outside the envelope (wind, bad GPS): stop the mission, raise one CRITICAL
        alarm and fly back over home, no higher than the envelope allows."""
        state = self.fc.state
        here = current_ned(state)
        breach = self.envelope.breach(here, state)
        if breach is None or here is None:
            self.envelope.outside = breach
            return
        if self.envelope.outside is not None:
            return
        self.envelope.outside = breach
        self.worker.stop_current("outside the flight envelope")
        self.raise_alarm("CRITICAL", f"Outside the flight envelope: {breach.message}")
        height = min(-here[2], self.envelope.envelope.max_height)
        self.navigation.hold_at((0.0, 0.0, -height))

    def _on_reading(self, sensor: str, reading: dict) -> None:
        self.failsafe.check_reading(sensor, reading)

    def _on_connection(self, connected: bool) -> None:
        if self.config.ground_link_topic is None or not connected:
            self.failsafe.link_changed(connected)
        if connected:
            self.gear.announce()

    # -- incoming -------------------------------------------------------------------------

    def _drop(self, reason: str, topic: str, detail: object) -> None:
        self.dropped[reason] += 1
        log.warning("dropped message on %s (%s): %s", topic, reason, detail)

    def _on_message(self, topic: str, payload: bytes) -> None:
        if topic == self.config.ground_link_topic:
            up = payload.strip() == b"1"
            log.info("ground link (bridge) %s", "up" if up else "down")
            self.failsafe.link_changed(up)
            return
        try:
            drone_id, channel, direction = protocol.split_topic(topic)
        except protocol.ProtocolError as exc:
            self._drop("topic", topic, exc)
            return
        if drone_id != self.drone_id or direction != "in":
            self._drop("topic", topic, "not one of this drone's input topics")
            return
        try:
            obj = protocol.decode_json(payload)
        except protocol.ProtocolError as exc:
            self._drop("json", topic, exc)
            return
        request_id = protocol.request_id_of(obj)
        if channel in ACT_ON and request_id is not None and self._recent.repeated(request_id):
            # QoS 1 and the ground's outbox both deliver at least once: act once.
            self._drop("repeated_request", topic, request_id)
            return
        handler = {
            "control": self._control,
            "mission": self._mission,
            "gear": self._gear_query,
            "alarms": self._alarm_ack,
            "envelope": self._envelope_update,
            "traffic": self._traffic,
        }
        handler[channel](topic, obj)

    def _control(self, topic: str, obj: Any) -> None:
        try:
            request = protocol.parse_control_request(obj)
            stale = self._stale(obj, self.config.max_control_age)
        except protocol.ProtocolError as exc:
            request_id = protocol.request_id_of(obj)
            if request_id is None:
                self._drop("control", topic, exc)
                return
            command = obj.get("command") if isinstance(obj.get("command"), str) else "unknown"
            self.dropped["control_refused"] += 1
            self.send(
                "control",
                protocol.ControlResponse(
                    request_id, command or "unknown", False, None, _sentence(exc)
                ),
            )
            return
        if stale is not None:
            self.dropped["control_stale"] += 1
            self.send(
                "control",
                protocol.ControlResponse(request.request_id, request.command, False, None, stale),
            )
            return
        if request.command not in READ_ONLY_COMMANDS:
            self.failsafe.ground_took_over()
        self._control_pool.submit(self._run_control, request)

    def _run_control(self, request: protocol.ControlRequest) -> None:
        try:
            response = self.controller.handle(request)
        except Exception as exc:  # Controller.handle should not raise; belt and braces
            log.exception("control %s crashed", request.command)
            response = protocol.ControlResponse(
                request.request_id, request.command, False, None, f"The agent failed: {exc}."
            )
        self.send("control", response)

    def _hold(self, params: dict, context: dict) -> dict:
        """Operator hold: a running mission is paused (resumable), else hover here."""
        if not self.fc.state.airborne:
            raise CommandError("The drone is on the ground; there is nothing to hold.")
        paused = self.worker.pause_current()
        if paused is not None:
            return {"mode": "hold", "mission_paused": paused}
        return {"mode": self.failsafe.hold_here("held by the operator")}

    def _return(self, params: dict, context: dict) -> dict:
        """Operator return: home at this altitude, land, disarm (lands here when the
        energy left would not get it home)."""
        if not self.fc.state.airborne:
            raise CommandError("The drone is on the ground; it is home already.")
        return {"mode": self.failsafe.return_home("return requested by the operator")}

    def _mission(self, topic: str, obj: Any) -> None:
        try:
            request = protocol.parse_mission_request(obj)
            follow_up = protocol.stop_follow_up(obj)
            # A stop is never too old: stopping is always safe.
            stale = (
                self._stale(obj, self.config.max_mission_age)
                if isinstance(request, protocol.MissionStart)
                else None
            )
        except protocol.ProtocolError as exc:
            request_id = protocol.request_id_of(obj)
            if request_id is None:
                self._drop("mission", topic, exc)
                return
            mission_id = obj.get("mission_id")
            if not isinstance(mission_id, str) or not mission_id:
                mission_id = "unknown"
            self.dropped["mission_refused"] += 1
            self.send(
                "mission",
                protocol.MissionProgress(
                    mission_id,
                    obj.get("assignment_id") if isinstance(obj.get("assignment_id"), str) else None,
                    "rejected",
                    error=_sentence(exc),
                    request_id=request_id,
                ),
            )
            return
        if stale is not None:
            self.dropped["mission_stale"] += 1
            self.send("mission", protocol.mission_reply(request, "rejected", error=stale))
            return
        if isinstance(request, protocol.MissionStart):
            self.failsafe.mission_requested()
        elif isinstance(request, protocol.MissionStop):
            self.failsafe.stop_requested(follow_up)
        self.worker.submit(request)

    def _stale(self, obj: Any, limit: float) -> str | None:
        """Why a request is too old to act on (its `ts` against the learnt clock offset)."""
        issued = protocol.issued_at(obj)
        if issued is None:
            return None
        age = self.ground_clock.age(issued)
        if age <= limit:
            return None
        log.warning("refused a request issued %.1f s ago (limit %g s)", age, limit)
        return (
            f"The request was issued {age:.0f} s ago, over the {limit:g} s limit: "
            "it was not acted on, so nothing queued while the drone was away flies late."
        )

    def _alarm_ack(self, topic: str, obj: Any) -> None:
        try:
            ack = protocol.parse_alarm_ack(obj)
        except protocol.ProtocolError as exc:
            self._drop("alarms", topic, exc)
            return
        self.failsafe.acknowledge(ack.level)

    def _gear_query(self, topic: str, obj: Any) -> None:
        try:
            query = protocol.parse_gear_query(obj)
        except protocol.ProtocolError as exc:
            request_id = protocol.request_id_of(obj)
            if request_id is None:
                self._drop("gear", topic, exc)
                return
            self.send("gear", protocol.GearReply(request_id, False, error=_sentence(exc)))
            return
        self.send("gear", self.gear.handle_query(query, self.fc.state))

    def _envelope_update(self, topic: str, obj: Any) -> None:
        """A new flight envelope from the ground; a malformed one leaves the old in force."""
        try:
            update = protocol.parse_envelope_update(obj)
        except protocol.ProtocolError as exc:
            self._drop("envelope", topic, exc)
            return
        envelope = self.envelope.update(update.envelope)
        self.remote_id.set_identity(update.remote_id)
        if update.log_collection is not None and self.collector is not None:
            self.collector.set_mode(update.log_collection)
        log.info(
            "flight envelope: %g m high, %g m from home, %d fence(s)",
            envelope.max_height,
            envelope.max_distance,
            len(envelope.polygons) + len(envelope.circles),
        )

    def _traffic(self, topic: str, obj: Any) -> None:
        """Other drones nearby and this drone's band, relayed by the ground; a malformed
        or stale message is counted by reason and changes nothing."""
        try:
            update = parse_traffic(obj)
        except TrafficError as exc:
            self._drop(f"traffic_{exc.reason}", topic, exc)
            return
        self.failsafe.band = update.band
        if not self.traffic.receive(update, self.ground_clock.age(update.ts)):
            self._drop("traffic_stale", topic, update.ts)

    def _keep_apart(self) -> None:
        """Predicted within the separation minima of a relayed drone: hold here as the
        operator's Hold does (a running mission paused, else the fail-safe's hold) and
        raise one CRITICAL alarm per encounter; only the operator moves the drone on."""
        for met in self.traffic.check():
            reason = (
                f"Separation: {met.other} predicted within the minima in {met.in_s:.1f} s "
                f"({met.horizontal_m:.0f} m apart, {met.vertical_m:.0f} m vertically); "
                "holding here"
            )
            if self.worker.pause_current() is None:
                self.failsafe.hold_here(reason)
            self.raise_alarm("CRITICAL", reason)


def fc_log_fetch(fc: FlightController, folder: Path, rate: float) -> Any:
    """The flight controller's log fetch (MAVLink's log protocol), or None when it has
    no log to fetch (UAVTalk boards keep none)."""
    if getattr(fc, "protocol", None) != "mavlink":
        return None
    from .fc.mavlink_logs import LogFetcher

    fetcher = LogFetcher(fc, folder, rate=rate)

    def fetch(stem: str) -> Path | None:
        return fetcher.fetch_newest("ulg" if fc.is_px4 else "bin", stem)  # type: ignore[attr-defined]

    return fetch


def failsafe_limits(config: AgentConfig) -> Limits:
    return Limits(
        battery_critical=config.battery_critical,
        battery_reserve=config.battery_reserve,
        alarm_repeat=config.alarm_repeat,
        critical_takeover=config.critical_takeover,
        link_loss_timeout=config.link_loss_timeout,
        link_loss_action=config.link_loss_action,
        return_speed=config.return_speed,
        auto_disarm_delay=config.auto_disarm_delay,
    )


class RecentIds:
    """The last `size` ids seen, to know a repeated one (called from one thread)."""

    def __init__(self, size: int) -> None:
        self._order: deque[str] = deque()
        self._seen: set[str] = set()
        self._size = size

    def repeated(self, value: str) -> bool:
        """True if `value` was seen before; else remember it."""
        if value in self._seen:
            return True
        self._seen.add(value)
        self._order.append(value)
        if len(self._order) > self._size:
            self._seen.discard(self._order.popleft())
        return False


def _sentence(exc: protocol.ProtocolError) -> str:
    return f"Bad {exc.field}: {exc.message}."


def wait_until(predicate: Any, timeout: float, interval: float = 0.05) -> bool:
    """Poll `predicate` until it is true or `timeout` passes (for tools and tests)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(interval)
    return bool(predicate())
