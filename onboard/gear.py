"""Gear Manager: drone specs and sensor list from JSON files, sensor readings, the camera.

specs.json and sensors.json (the gear files of [Paula 2018], listings 4.1 and 4.2) are read from a
configurable folder and re-read periodically; a change is announced on `<id>/gear/out`.
An optional sensor_field.json there places simulated plumes (see sensors.py).
"""

from __future__ import annotations

import json
import logging
import re
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from . import protocol
from .fc.base import VehicleState
from .sensors import SensorConfigError, SensorField, load_field
from .wind import WindLimitError, limit_from_specs

log = logging.getLogger(__name__)

SPECS_FILE = "specs.json"
SENSORS_FILE = "sensors.json"
FIELD_FILE = "sensor_field.json"

Send = Callable[[str, Any], None]  # (channel, message)


class GearError(Exception):
    """A gear request that cannot be served; str() is a sentence for the reply."""


def sensor_names(sensors: dict) -> dict[str, str]:
    """Leaf sensors of a sensors.json tree → {name: model}: {"GAS": {"CO2": "X"}} → {"CO2": "X"}."""
    names: dict[str, str] = {}
    for key, value in sensors.items():
        if isinstance(value, dict):
            names.update(sensor_names(value))
        else:
            names[str(key)] = str(value)
    return names


class GearManager:
    def __init__(
        self,
        folder: str | Path | None,
        send: Send,
        *,
        reread_interval: float = 5.0,
        sensor_field: SensorField | None = None,
        pictures_dir: str | Path | None = None,
        camera: str = "sim",
    ) -> None:
        self.folder = Path(folder) if folder else None
        self.send = send
        self.reread_interval = reread_interval
        self._cli_field = sensor_field
        self.field = sensor_field or SensorField()
        self.pictures_dir = Path(pictures_dir) if pictures_dir else None
        self.camera = camera
        self.specs: dict = {}
        self.sensors: dict = {}
        self.errors = 0
        self._mtimes: dict[str, float | None] = {}
        self._lock = threading.Lock()
        self._picture_lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.reload()

    # -- files ----------------------------------------------------------------------------

    def _read_json(self, name: str) -> dict | None:
        """The file's object; None when it is absent or broken (the last good one stays)."""
        assert self.folder is not None
        path = self.folder / name
        try:
            data = json.loads(path.read_text())
        except FileNotFoundError:
            return {}
        except (OSError, ValueError) as exc:
            self.errors += 1
            log.warning("ignoring %s: %s", path, exc)
            return None
        if not isinstance(data, dict):
            self.errors += 1
            log.warning("ignoring %s: not a JSON object", path)
            return None
        return data

    def _checked_specs(self, specs: dict | None) -> dict | None:
        """The specs, or None (the last good ones stay) when a limit in them is malformed:
        a negative wind limit must not become the drone's rule."""
        if specs is None:
            return None
        try:
            limit_from_specs(specs)
        except WindLimitError as exc:
            self.errors += 1
            log.warning("ignoring %s: %s", SPECS_FILE, exc)
            return None
        return specs

    def _stamp(self) -> dict[str, float | None]:
        stamps: dict[str, float | None] = {}
        for name in (SPECS_FILE, SENSORS_FILE, FIELD_FILE):
            try:
                stat = (self.folder / name).stat()  # type: ignore[operator]
                stamps[name] = stat.st_mtime_ns + stat.st_size * 1e-3
            except OSError:
                stamps[name] = None
        return stamps

    def reload(self) -> bool:
        """Re-read the files; True when specs or sensors changed."""
        if self.folder is None:
            return False
        stamps = self._stamp()
        if stamps == self._mtimes:
            return False
        self._mtimes = stamps
        specs = self._checked_specs(self._read_json(SPECS_FILE))
        sensors = self._read_json(SENSORS_FILE)
        if self._cli_field is None and stamps[FIELD_FILE] is not None:
            try:
                self.field = load_field(self.folder / FIELD_FILE)
            except (OSError, ValueError, SensorConfigError) as exc:
                self.errors += 1
                log.warning("ignoring %s: %s", FIELD_FILE, exc)
        with self._lock:
            changed = False
            if specs is not None and specs != self.specs:
                self.specs, changed = specs, True
            if sensors is not None and sensors != self.sensors:
                self.sensors, changed = sensors, True
        return changed

    def announcement(self) -> protocol.GearAnnouncement:
        with self._lock:
            return protocol.GearAnnouncement(dict(self.specs), dict(self.sensors))

    def announce(self) -> None:
        self.send("gear", self.announcement())

    def start(self) -> None:
        self._thread = threading.Thread(target=self._run, name="gear", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(2)

    def _run(self) -> None:
        while not self._stop.wait(self.reread_interval):
            try:
                if self.reload():
                    self.announce()
            except Exception:
                log.exception("gear re-read failed")

    # -- queries --------------------------------------------------------------------------

    def handle_query(self, query: protocol.GearQuery, state: VehicleState) -> protocol.GearReply:
        with self._lock:
            specs, sensors = dict(self.specs), dict(self.sensors)
        if query.query == "specs":
            return protocol.GearReply(query.request_id, True, specs=specs)
        if query.query == "sensors":
            return protocol.GearReply(query.request_id, True, sensors=sensors)
        try:
            reading = self.read(query.sensor or "", state)
        except GearError as exc:
            return protocol.GearReply(query.request_id, False, error=str(exc))
        return protocol.GearReply(query.request_id, True, reading=reading)

    def read(self, sensor: str, state: VehicleState) -> dict:
        """A reading of a sensor in the gear list, at the drone's position."""
        with self._lock:
            names = sensor_names(self.sensors)
        if sensor not in names:
            known = ", ".join(sorted(names)) or "none"
            raise GearError(f"This drone has no sensor named {sensor!r} (it has: {known}).")
        try:
            reading = self.field.read(sensor, state.lat, state.lon, state.alt)
        except KeyError as exc:
            raise GearError(str(exc.args[0])) from None
        reading["model"] = names[sensor]
        return reading

    # -- camera ---------------------------------------------------------------------------

    def has_camera(self) -> bool:
        with self._lock:
            return "CAMERA" in sensor_names(self.sensors)

    def _next_name(self) -> str:
        assert self.pictures_dir is not None
        numbers = [
            int(m.group(1))
            for p in self.pictures_dir.glob("IMG_*.JPG")
            if (m := re.fullmatch(r"IMG_(\d+)\.JPG", p.name))
        ]
        return f"IMG_{max(numbers, default=0) + 1:04d}.JPG"

    def _render(self, state: VehicleState) -> bytes:
        if self.camera != "sim":
            raise GearError("Only the simulated camera is supported on this drone.")
        try:
            from .synthetic_camera import render_nadir
        except ImportError as exc:
            raise GearError(str(exc)) from None
        if state.lat is None or state.lon is None or state.home is None:
            raise GearError("The drone has no GPS fix or home yet, so the picture has no place.")
        return render_nadir(
            state.lat,
            state.lon,
            state.alt or 0.0,
            state.yaw or 0.0,
            home=(state.home[0], state.home[1]),
        )

    def take_picture(self, state: VehicleState, context: dict | None = None) -> dict:
        """Take, store and publish one picture; the result names it."""
        if not self.has_camera():
            raise GearError("This drone has no camera in its gear list.")
        if self.pictures_dir is None:
            raise GearError("No folder is configured for pictures.")
        context = context or {}
        jpeg = self._render(state)
        with self._picture_lock:
            self.pictures_dir.mkdir(parents=True, exist_ok=True)
            name = self._next_name()
            (self.pictures_dir / name).write_bytes(jpeg)
        position = None
        if state.lat is not None and state.lon is not None:
            position = protocol.Position(state.lat, state.lon, state.alt or 0.0)
        attitude = {"roll": state.roll, "pitch": state.pitch, "yaw": state.yaw}
        self.send(
            "pictures",
            protocol.Picture(
                name=name,
                position=position,
                attitude=attitude,
                mission_id=context.get("mission_id"),
                index=context.get("index"),
                jpeg=jpeg,
                ts=time.time(),
                assignment_id=context.get("assignment_id"),
            ),
        )
        return {"name": name, "bytes": len(jpeg)}
