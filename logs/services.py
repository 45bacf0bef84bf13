"""What the API, the pages and the import task do with flight logs, in one place.

The parsing, storage and analysis themselves are the Django-free core (`importers`,
`store`, `analysis`); this module ties them to rows, folders, limits and progress events.
"""

from __future__ import annotations

import logging
import math
import os
import shutil
import threading
import time
import uuid
from collections import OrderedDict
from collections.abc import Callable

import numpy as np
from asgiref.sync import async_to_sync
from celery.exceptions import SoftTimeLimitExceeded
from channels.layers import get_channel_layer
from django.conf import settings
from django.db import transaction
from django.utils import timezone
from django.utils.module_loading import import_string

from logs import attempts, reports, trends, units
from logs.analysis import trajectory_of, values_at, values_tree
from logs.importers.base import Limits, LogFormatError
from logs.models import FlightLog, LogStatus
from logs.store import LogStore
from logs.uploads import StoredUpload

logger = logging.getLogger(__name__)

# Progress goes to the database and the page at most this often (a 1 GB import reports
# hundreds of fractions; each one is an UPDATE and a Redis publish).
PROGRESS_INTERVAL_S = 0.25
GENERIC_FAILURE = "The file could not be processed because of an internal error; we logged it."


def limits() -> Limits:
    return Limits(
        max_file_bytes=int(settings.LOG_UPLOAD_MAX_BYTES),
        max_uncompressed_bytes=int(settings.LOGS_MAX_UNCOMPRESSED_BYTES),
        max_compression_ratio=float(settings.LOGS_MAX_COMPRESSION_RATIO),
    )


def create_log(*, organisation, owner, upload: StoredUpload) -> FlightLog:  # type: ignore[no-untyped-def]
    """A `processing` row for an upload already on disk; the import is queued on commit."""
    from logs.tasks import import_flight_log

    name = os.path.basename(upload.name or "log")[:255] or "log"
    log = FlightLog(organisation=organisation, owner=owner, name=name, size=upload.size or 0)
    log.upload_path.parent.mkdir(parents=True, exist_ok=True)
    os.replace(upload.path, log.upload_path)
    try:
        log.save()
    except BaseException:
        shutil.rmtree(log.directory, ignore_errors=True)
        raise
    # Routed by config/queues.py to LOGS_IMPORT_QUEUE. Should the broker be away now, the
    # sweep finds the log queued long ago and never started, and queues it again.
    transaction.on_commit(lambda: import_flight_log.delay(str(log.pk)))
    return log


def delete_log(log: FlightLog) -> None:
    directory = log.directory
    forget_store(log)
    log.delete()
    transaction.on_commit(lambda: shutil.rmtree(directory, ignore_errors=True))


def publish(log: FlightLog, payload: dict) -> None:
    """Push a progress or status event to the log's page; a missing Redis never fails the
    import (the page also polls the API)."""
    layer = get_channel_layer()
    if layer is None:
        return
    try:
        async_to_sync(layer.group_send)(
            log.group_name, {"type": "flightlog.event", "payload": payload}
        )
    except Exception as exc:  # noqa: BLE001 - progress is best effort; the import goes on
        # No traceback kept: its frames would pin the reader's memory-mapped buffers.
        logger.warning("could not publish progress of log %s: %s", log.pk, exc)


def _progress_reporter(log: FlightLog) -> Callable[[float], None]:
    last = [0.0]

    def report(fraction: float) -> None:
        now = time.monotonic()
        if now - last[0] < PROGRESS_INTERVAL_S:
            return
        last[0] = now
        # Parsing is most of the work; writing the store is the last 5 %.
        value = round(min(max(fraction, 0.0), 1.0) * 0.95, 4)
        FlightLog.objects.filter(pk=log.pk, status=LogStatus.PROCESSING).update(progress=value)
        publish(log, {"type": "progress", "progress": value, "status": LogStatus.PROCESSING})

    return report


def _finish(log: FlightLog, **fields: object) -> bool:
    """Compare-and-set out of `processing`; False when the log was deleted or finished."""
    changed = FlightLog.objects.filter(pk=log.pk, status=LogStatus.PROCESSING).update(
        processed_at=timezone.now(), **fields
    )
    return changed == 1


def fail(log: FlightLog, message: str) -> None:
    shutil.rmtree(log.store_path, ignore_errors=True)
    if _finish(log, status=LogStatus.FAILED, error=message, progress=1.0):
        publish(log, {"type": "status", "status": LogStatus.FAILED, "error": message})


def process_log(log_id: str, task_id: str | None = None) -> str:
    """Parse an uploaded log into its columnar store; returns the final status.

    `task_id` names the delivery (a redelivery of the same message may take the log back);
    a log another live delivery holds is left to it. Any bad file ends as `failed` with
    one sentence for the user and no store on disk; a file that kills the worker process
    instead is failed once it did so LOGS_IMPORT_REDELIVERY_LIMIT times.
    """
    attempt = attempts.claim(log_id, task_id or f"direct-{uuid.uuid4()}")
    log = FlightLog.objects.filter(pk=log_id).first()
    if log is None or attempt is None:
        return log.status if log else "deleted"
    if attempts.over_limit(attempt):
        fail(log, attempts.crash_reason(attempt - 1))
        return LogStatus.FAILED
    publish(log, {"type": "progress", "progress": 0.0, "status": LogStatus.PROCESSING})
    with attempts.heartbeat(log.pk, log.import_task):
        return _import(log)


def _import(log: FlightLog) -> str:
    importer = import_string(settings.LOGS_IMPORT_FUNCTION)
    try:
        store = importer(
            log.upload_path, log.store_path, limits=limits(), progress=_progress_reporter(log)
        )
        index = store.index
    except LogFormatError as exc:
        fail(log, str(exc))
        return LogStatus.FAILED
    except MemoryError:
        fail(log, "The file is too large to process on this server.")
        return LogStatus.FAILED
    except SoftTimeLimitExceeded:
        fail(log, "Processing the file took longer than the time limit.")
        return LogStatus.FAILED
    except Exception:
        logger.exception("importing log %s (%s) failed", log.pk, log.name)
        fail(log, GENERIC_FAILURE)
        return LogStatus.FAILED
    _check(log, store)
    done = _finish(
        log,
        status=LogStatus.READY,
        progress=1.0,
        format=index["format"],
        series_count=len(index["series"]),
        start_s=index["start"],
        end_s=index["end"],
    )
    if not done:  # deleted while we parsed: leave nothing behind
        shutil.rmtree(log.directory, ignore_errors=True)
        return "deleted"
    publish(log, {"type": "status", "status": LogStatus.READY, "progress": 1.0})
    _judge_trends(log)
    return LogStatus.READY


def _check(log: FlightLog, store: LogStore) -> None:
    """The log's health report (logs.reports); a check that cannot run never fails the
    import, and the report is made again when first asked for."""
    try:
        reports.check(log, store)
    except Exception:
        logger.exception("checking log %s (%s) failed", log.pk, log.name)


def _judge_trends(log: FlightLog) -> None:
    """A log of a drone is judged against the drone's history and the fleet (logs.trends);
    a failure there never fails the import."""
    try:
        log.refresh_from_db()
        trends.evaluate(log)
    except Exception:
        logger.exception("judging the trends of log %s (%s) failed", log.pk, log.name)


def sweep_stuck() -> dict[str, list[str]]:
    """Queue again, or fail, the logs processing with no worker (logs.attempts.stuck_logs):
    failed when their attempts reached the limit, else queued once more."""
    from logs.tasks import import_flight_log

    done: dict[str, list[str]] = {"requeued": [], "failed": []}
    for log in attempts.stuck_logs():
        if log.attempts >= int(settings.LOGS_IMPORT_REDELIVERY_LIMIT):
            fail(log, attempts.crash_reason(log.attempts))
            done["failed"].append(str(log.pk))
        elif attempts.mark_requeued(log):
            import_flight_log.delay(str(log.pk))
            done["requeued"].append(str(log.pk))
    if done["requeued"] or done["failed"]:
        logger.warning("logs stuck in processing: %s", done)
    return done


# --- reading a ready log ---


class CachedStore(LogStore):
    """A store that keeps its small arrays in memory: a log with a thousand series would
    otherwise re-open a thousand files for every values-at-time request of a replay.

    Copies, not memory maps: every map holds a file descriptor, and thousands of them push
    a process's descriptors past what select() can watch. Large arrays stay memory-mapped
    per request, and the copies of one store stay within CACHE_BYTES."""

    ARRAY_BYTES = 4 * 1024 * 1024
    CACHE_BYTES = 96 * 1024 * 1024

    def __init__(self, directory) -> None:  # type: ignore[no-untyped-def]
        super().__init__(directory)
        self._arrays: dict[str, np.ndarray] = {}
        self._bytes = 0

    def _load(self, name: str) -> np.ndarray:
        cached = self._arrays.get(name)
        if cached is not None:
            return cached
        mapped = super()._load(name)
        if mapped.nbytes > self.ARRAY_BYTES or self._bytes + mapped.nbytes > self.CACHE_BYTES:
            return mapped
        copy = np.array(mapped)  # the map (and its descriptor) goes with `mapped`
        copy.setflags(write=False)
        self._arrays[name] = copy
        self._bytes += copy.nbytes
        return copy


_STORES: OrderedDict[tuple[str, int], CachedStore] = OrderedDict()
_STORES_LOCK = threading.Lock()
STORE_CACHE_SIZE = 8


def store_of(log: FlightLog) -> LogStore:
    """The log's store, kept open per process for the few logs being looked at."""
    index = log.store_path / "index.json"
    key = (str(log.store_path), index.stat().st_mtime_ns)
    with _STORES_LOCK:
        store = _STORES.get(key)
        if store is not None:
            _STORES.move_to_end(key)
            return store
    store = CachedStore(log.store_path)
    with _STORES_LOCK:
        _STORES[key] = store
        while len(_STORES) > STORE_CACHE_SIZE:
            _STORES.popitem(last=False)
    return store


def forget_store(log: FlightLog) -> None:
    with _STORES_LOCK:
        for key in [k for k in _STORES if k[0] == str(log.store_path)]:
            del _STORES[key]


def shown(info: dict) -> units.Display:
    """The display unit and factor of a stored series; enumerations and text stay as they are."""
    if info["kind"] not in ("int", "double"):
        return units.Display(info["unit"])
    return units.display(info["unit"])


def series_list(store: LogStore) -> list[dict]:
    """Every series' summary, in display units ("recorded_unit" is the file's own)."""
    return [
        {
            "path": path,
            "unit": shown(info).unit,
            "recorded_unit": info["unit"],
            "count": info["count"],
            "start": info["start"],
            "end": info["end"],
            "kind": info["kind"],
            "time_source": info["time_source"],
            "labels": info["labels"],
        }
        for path, info in store.index["series"].items()
    ]


def values_at_time(store: LogStore, t: float) -> dict:
    """Every value at or before t, nested by group; NaN and infinities become None (JSON)."""
    flat = values_at(store, t)
    for path, entry in flat.items():
        if entry is None or isinstance(entry["value"], bool):
            continue
        display = shown(store.info(path))
        if display.converts and isinstance(entry["value"], int | float):
            entry["value"] = entry["value"] * display.factor
        if isinstance(entry["value"], float) and not math.isfinite(entry["value"]):
            entry["value"] = None
    return values_tree(flat)


def plot(store: LogStore, path: str, **window: float | int | None) -> dict:
    """The series endpoint's {"t", "v", "unit"}, in the display unit."""
    data = store.plot(path, **window)  # type: ignore[arg-type]
    display = shown(store.info(path))
    if display.converts:
        data["v"] = [
            v * display.factor if isinstance(v, int | float) and not isinstance(v, bool) else v
            for v in data["v"]
        ]
    return {**data, "unit": display.unit}


def layer_times(store: LogStore) -> dict[str, np.ndarray]:
    """Per layer, the time stamps of its densest series (a message's fields share them)."""
    best: dict[str, tuple[int, str]] = {}
    for path, info in store.index["series"].items():
        layer = path.split("/", 1)[0]
        if info["count"] > best.get(layer, (-1, ""))[0]:
            best[layer] = (info["count"], path)
    return {layer: store.read_ns(path)[0] for layer, (_, path) in best.items()}


def _decimate(n: int, points: int) -> np.ndarray:
    """Evenly spaced indices (first and last kept): a path, unlike a plot, needs its order."""
    if n <= points:
        return np.arange(n)
    return np.unique(np.linspace(0, n - 1, points).round().astype(np.int64))


def _finite(values: np.ndarray) -> list:
    return [v if math.isfinite(v) else None for v in np.asarray(values, float).tolist()]


def _degrees(values: np.ndarray) -> np.ndarray:
    values = np.asarray(values, dtype=np.float64)
    # MAVLink and some PX4 topics keep degrees x 1e7 in integers.
    if len(values) and np.nanmax(np.abs(values)) > 360:
        return values / 1e7
    return values


MAX_TRACKS = 8


def _gps_pairs(store: LogStore) -> list[tuple[str, str, str]]:
    """(name, lat path, lon path) of every GPS track the core found: the log's main one
    first, then one per layer (each drone of a mission log)."""
    candidates = [store.special.get("gps") or []]
    candidates += [
        found.get("gps") or [] for found in store.index.get("special_by_layer", {}).values()
    ]
    pairs: list[tuple[str, str, str]] = []
    for gps in candidates:
        if len(gps) >= 2 and gps[0] not in {p[1] for p in pairs}:
            pairs.append((gps[0].rsplit("/", 1)[0], gps[0], gps[1]))
    return pairs[:MAX_TRACKS]


def _gps_track(store: LogStore, name: str, lat_path: str, lon_path: str, points: int) -> dict:
    t, lat = store.read(lat_path)
    _, lon = store.read(lon_path)
    n = min(len(lat), len(lon))
    lat, lon, t = _degrees(lat[:n]), _degrees(lon[:n]), t[:n]
    ok = np.isfinite(lat) & np.isfinite(lon) & ~((lat == 0) & (lon == 0))
    t, lat, lon = t[ok], lat[ok], lon[ok]
    idx = _decimate(len(t), points)
    return {"name": name, "t": t[idx].tolist(), "lat": lat[idx].tolist(), "lon": lon[idx].tolist()}


def track(store: LogStore, *, points: int = 2000) -> dict:
    """The paths to draw on the map: every GPS track recorded (the main one first, then
    e.g. the other drones of a mission log), else the trajectory estimated from velocity
    and yaw (north and west of the start), else nothing. The first track's t/lat/lon are
    also at the top level."""
    tracks = [
        found
        for found in (_gps_track(store, *pair, points) for pair in _gps_pairs(store))
        if len(found["t"]) >= 1
    ]
    if tracks:
        first = tracks[0]
        return {
            "source": "gps",
            "t": first["t"],
            "lat": first["lat"],
            "lon": first["lon"],
            "tracks": tracks,
        }
    trajectory = trajectory_of(store)
    if trajectory is not None and len(trajectory.t):
        idx = _decimate(len(trajectory.t), points)
        return {
            "source": "estimated",
            "unit": trajectory.unit,
            "t": trajectory.t[idx].tolist(),
            "x": _finite(trajectory.x[idx]),
            "y": _finite(trajectory.y[idx]),
        }
    return {"source": None, "t": []}


def attitude(store: LogStore, *, points: int = 4000) -> dict:
    """Roll, pitch and yaw in radians on the roll series' time stamps, for the 3D view."""
    rotation = store.special.get("rotation") or []
    if len(rotation) < 3:
        return {"t": [], "roll": [], "pitch": [], "yaw": []}
    t, roll = store.read(rotation[0])
    out: dict[str, list] = {}
    idx = _decimate(len(t), points)
    for name, path in zip(("roll", "pitch", "yaw"), rotation, strict=False):
        ts, values = store.read(path)
        values = np.asarray(values, dtype=np.float64)
        if store.info(path)["unit"].lower() in ("deg", "degree", "degrees", "°", "cdeg"):
            values = np.radians(values / (100 if store.info(path)["unit"] == "cdeg" else 1))
        if len(ts) != len(t) or not np.array_equal(ts, t):
            values = np.interp(t, ts, values) if len(ts) else np.full(len(t), np.nan)
        out[name] = _finite(values[idx])
    return {"t": t[idx].tolist(), **out}


def parse_float(raw: str | None, name: str) -> float | None:
    """A finite float query parameter, or ValueError naming it."""
    if raw in (None, ""):
        return None
    try:
        value = float(raw)
    except ValueError:
        raise ValueError(f"{name} must be a number of seconds.") from None
    if not math.isfinite(value):
        raise ValueError(f"{name} must be a finite number.")
    return value
