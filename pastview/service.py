"""The ground's past-view service: one ``PastView`` per drone, fed from the broker.

Camera frames come from ``<id>/camera/out``; poses from ``<id>/telemetry/out``, either the
agent's ``Pose`` objects (``onboard/video.py``, up to 200 Hz) or, for a drone that sends
none, the flight controller's ``AttitudeActual`` quaternion fused with the latest
``PositionActual``. Every pose is evaluated; what reaches the page is throttled to
``push_hz`` per drone, except that a change of the chosen frame (with its JPEG) and a
tracking lost/found event are pushed at once. No MQTT, Redis or Django here: the
management command (``manage.py pastview``) wires ``publish`` and ``remember`` to the
Channels layer and Redis, and the tests call ``handle`` directly.

Threading: ``handle`` runs on the MQTT thread, ``flush`` on the command's main loop; one
lock guards the per-drone state.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from onboard import protocol
from onboard.video import POSE_OBJECT
from pastview.evaluation import Spirit
from pastview.selection import PastView, PastViewSettings

log = logging.getLogger(__name__)

# The simulated camera's mount (firmware/sim/camera.py): the page must draw with the same
# field of view and tilt as the pictures were taken with, and SPIRIT's centrality term
# must measure along the same axis.
DEFAULT_CAMERA = {"fov_deg": 90.0, "pitch_down_deg": 30.0}

Publish = Callable[[str, dict[str, Any]], None]
Remember = Callable[[str, dict[str, Any]], None]


def group_name(drone_id: str) -> str:
    """The Channels group the pages of one drone's past view listen on."""
    return f"pastview-{drone_id}"


def default_settings() -> PastViewSettings:
    return PastViewSettings(
        evaluation=Spirit(camera_pitch_down_deg=DEFAULT_CAMERA["pitch_down_deg"])
    )


@dataclass
class DroneView:
    """One drone's view and what the page has been sent of it."""

    view: PastView
    pending: dict[str, Any] | None = None
    last_push: float = -math.inf
    last_remember: float = -math.inf
    last_live_ts: float | None = None
    pose_stream: bool = False  # the agent sends Pose objects: ignore the FC fallback
    fc_position: list[float] | None = None
    fc_orientation: list[float] | None = None
    frame: dict[str, Any] | None = None  # the chosen frame's info and JPEG, for snapshots
    seen_at: float = field(default_factory=time.monotonic)


class PastViewService:
    """Routes broker messages to per-drone past views and pushes the results."""

    def __init__(
        self,
        *,
        publish: Publish,
        remember: Remember | None = None,
        settings_for: Callable[[str], PastViewSettings | None] | None = None,
        push_hz: float = 30.0,
        remember_every_s: float = 1.0,
        max_drones: int = 1000,
        idle_after_s: float = 600.0,
    ) -> None:
        if push_hz <= 0:
            raise ValueError(f"push_hz must be positive, got {push_hz}")
        self.publish = publish
        self.remember = remember
        self.settings_for = settings_for or (lambda drone_id: None)
        self.push_period = 1.0 / push_hz
        self.remember_every_s = remember_every_s
        self.max_drones = max_drones
        self.idle_after_s = idle_after_s
        self.drones: dict[str, DroneView] = {}
        self.counters: Counter[str] = Counter()
        # Drones a page is open on; None pushes for every drone. Unwatched drones are still
        # evaluated (their buffers must fill) and remembered, just not pushed.
        self.watched: set[str] | None = None
        self._lock = threading.Lock()

    # -- inbound ----------------------------------------------------------------------------

    def handle(self, topic: str, payload: bytes, now: float | None = None) -> str | None:
        """One broker message; None when used, else why it was dropped (also counted)."""
        now = time.monotonic() if now is None else now
        self.counters["received"] += 1
        reason = self._handle(topic, payload, now)
        if reason is not None:
            self.counters[f"dropped.{reason}"] += 1
        return reason

    def _handle(self, topic: str, payload: bytes, now: float) -> str | None:
        try:
            drone_id, channel, direction = protocol.split_topic(topic)
        except protocol.ProtocolError:
            return "bad_topic"
        if direction != "out" or channel not in ("camera", "telemetry"):
            return "bad_topic"
        try:
            message = protocol.decode_json(payload)
        except protocol.ProtocolError:
            return "malformed"
        if not isinstance(message, dict):
            return "malformed"
        with self._lock:
            drone = self._drone(drone_id, now)
            if drone is None:
                return "too_many_drones"
            drone.seen_at = now
            if channel == "camera":
                return self._camera(drone_id, drone, message, now)
            return self._telemetry(drone_id, drone, message, now)

    def _drone(self, drone_id: str, now: float) -> DroneView | None:
        drone = self.drones.get(drone_id)
        if drone is not None:
            return drone
        self._evict_idle(now)
        if len(self.drones) >= self.max_drones:
            return None
        try:
            settings = self.settings_for(drone_id) or default_settings()
        except Exception:  # noqa: BLE001 - a settings store outage must not stop the view
            log.exception("settings of %s unavailable; using defaults", drone_id)
            settings = default_settings()
        drone = DroneView(PastView(settings))
        self.drones[drone_id] = drone
        return drone

    def _evict_idle(self, now: float) -> None:
        for drone_id, drone in list(self.drones.items()):
            if now - drone.seen_at > self.idle_after_s:
                del self.drones[drone_id]
                self.counters["evicted_idle"] += 1

    def _camera(self, drone_id: str, drone: DroneView, message: dict, now: float) -> str | None:
        malformed = drone.view.stats.frames_malformed
        late = drone.view.stats.frames_out_of_order
        drone.view.add_frame(message)
        if drone.view.stats.frames_malformed > malformed:
            return "malformed"
        if drone.view.stats.frames_out_of_order > late:
            return "out_of_order"
        live = drone.view.live_frame()
        if live is not None and live["ts"] != drone.last_live_ts:
            drone.last_live_ts = live["ts"]
            self._send(drone_id, {"type": "live", **live})
        return None

    def _telemetry(self, drone_id: str, drone: DroneView, message: dict, now: float) -> str | None:
        objects = message.get("objects")
        if not isinstance(objects, list):
            return "malformed"
        used = 0
        for obj in objects:
            if not isinstance(obj, dict) or not isinstance(obj.get("fields"), dict):
                self.counters["dropped.bad_object"] += 1
                continue
            name, fields, ts = obj.get("name"), obj["fields"], obj.get("ts")
            pose: tuple[Any, Any] | None = None
            if name == POSE_OBJECT:
                drone.pose_stream = True
                pose = (
                    [fields.get(k) for k in ("North", "East", "Down")],
                    [fields.get(k) for k in ("qx", "qy", "qz", "qw")],
                )
            elif drone.pose_stream:
                continue
            elif name == "PositionActual":
                drone.fc_position = [fields.get(k) for k in ("North", "East", "Down")]
                if drone.fc_orientation is not None:
                    pose = (drone.fc_position, drone.fc_orientation)
            elif name == "AttitudeActual":
                # dRonin's q1 is the scalar part; poses are (qx, qy, qz, qw).
                drone.fc_orientation = [fields.get(k) for k in ("q2", "q3", "q4", "q1")]
                if drone.fc_position is not None:
                    pose = (drone.fc_position, drone.fc_orientation)
            if pose is not None:
                used += 1
                self._pose(drone_id, drone, ts, pose[0], pose[1], now)
        return None if used else "no_pose"

    def _pose(
        self, drone_id: str, drone: DroneView, ts: Any, position: Any, orientation: Any, now: float
    ) -> None:
        try:
            update = drone.view.update_pose(ts, position, orientation)
        except (TypeError, ValueError) as exc:  # PastView refuses bad poses itself; belt and braces
            update = None
            log.info("pose of %s refused: %s", drone_id, exc)
        if update is None:
            self.counters["poses_refused"] += 1
            return
        self.counters["poses"] += 1
        if update["changed"]:
            drone.frame = {"frame": update["frame"], "jpeg": update["jpeg"]}
        message = {"type": "update", **update}
        if update["changed"] or update["event"] or now - drone.last_push >= self.push_period:
            # A new frame or a lost/found event cannot wait for the next slot.
            drone.pending = None
            drone.last_push = now
            self._send(drone_id, message)
        else:
            drone.pending = message
        if update["changed"] or now - drone.last_remember >= self.remember_every_s:
            drone.last_remember = now
            self._remember(drone_id, drone, message)

    # -- outbound ---------------------------------------------------------------------------

    def flush(self, now: float | None = None) -> int:
        """Push the latest held-back update of every drone whose slot has come; how many."""
        now = time.monotonic() if now is None else now
        sent = 0
        with self._lock:
            for drone_id, drone in self.drones.items():
                if drone.pending is not None and now - drone.last_push >= self.push_period:
                    message, drone.pending = drone.pending, None
                    drone.last_push = now
                    self._send(drone_id, message)
                    sent += 1
        return sent

    def _send(self, drone_id: str, message: dict[str, Any]) -> None:
        if self.watched is not None and drone_id not in self.watched:
            self.counters["unwatched"] += 1
            return
        try:
            self.publish(drone_id, message)
            self.counters[f"pushed.{message['type']}"] += 1
        except Exception:  # noqa: BLE001 - a Redis hiccup loses one update, not the service
            self.counters["push_failed"] += 1
            log.exception("push to %s failed", group_name(drone_id))

    def _remember(self, drone_id: str, drone: DroneView, update: dict[str, Any]) -> None:
        if self.remember is None:
            return
        snapshot = {
            "update": {**update, "jpeg": drone.frame["jpeg"] if drone.frame else None},
            "live": drone.view.live_frame(),
            "status": drone.view.status(),
        }
        try:
            self.remember(drone_id, snapshot)
        except Exception:  # noqa: BLE001
            self.counters["remember_failed"] += 1
            log.exception("snapshot of %s not stored", drone_id)

    # -- settings and status ----------------------------------------------------------------

    def apply_settings(self, drone_id: str, settings: PastViewSettings) -> None:
        """New settings for a drone: a new evaluation takes effect on the next pose; a new
        buffer shape or video rate restarts its view (the stored frames are dropped)."""
        with self._lock:
            drone = self.drones.get(drone_id)
            if drone is None:
                return
            old = drone.view.settings
            if _same_except_evaluation(old, settings):
                drone.view.set_evaluation(settings.evaluation)
            else:
                drone.view = PastView(settings)
                drone.frame = None
        self._send(drone_id, {"type": "settings", "settings": settings.to_dict()})

    def status(self, drone_id: str) -> dict[str, Any] | None:
        with self._lock:
            drone = self.drones.get(drone_id)
            return None if drone is None else drone.view.status()

    def publish_status(self) -> None:
        """Counters of every drone to its pages (the command calls this every few seconds)."""
        with self._lock:
            statuses = {d: v.view.status() for d, v in self.drones.items()}
        for drone_id, status in statuses.items():
            self._send(drone_id, {"type": "status", **status})


def _same_except_evaluation(a: PastViewSettings, b: PastViewSettings) -> bool:
    left, right = a.to_dict(), b.to_dict()
    left.pop("evaluation")
    right.pop("evaluation")
    return left == right
