"""The mission log: one JSON document with the mission, its drones, its
assignments and every event, readable by the log viewer page and by
`logs.importers.mission` (events with `ts`, `drone_id`, `type`, `status`,
`index`, `position`, `duration_s`).
"""

from __future__ import annotations

import json
from collections import defaultdict
from typing import Any

from missions.errors import MissionError
from missions.models import Assignment, Event, Mission, Step

FORMAT = "skyhive-mission-log"
VERSION = 1
MAX_LOG_BYTES = 50 * 1024 * 1024


def _iso(value: Any) -> str | None:
    return value.isoformat() if value is not None else None


def build_log(mission: Mission) -> dict:
    """Everything that happened in the mission, as a plain JSON-ready document."""
    assignments = list(mission.assignments.select_related("drone").order_by("created_at"))
    events = list(mission.events.select_related("drone").order_by("at", "id"))
    steps = list(mission.steps.select_related("drone").order_by("index"))
    drones = {a.drone.drone_id: a.drone for a in assignments}
    for step in steps:
        if step.drone is not None:
            drones.setdefault(step.drone.drone_id, step.drone)
    return {
        "format": FORMAT,
        "version": VERSION,
        "mission": _mission_row(mission),
        "drones": [
            {"id": drone_id, "name": drone.name or drone_id} for drone_id, drone in drones.items()
        ],
        "assignments": [_assignment_row(a) for a in assignments],
        "steps": [_step_row(s) for s in steps],
        "stages": stages(steps),
        "events": [_event_row(event) for event in events],
    }


# Event data worth a column of its own in the log (the importer reads these).
_EVENT_FIELDS = (
    "index",
    "command",
    "status",
    "position",
    "duration_s",
    "level",
    "decode_ms",
    "error",
    "assignment",
    "ignored",
    "decision",
    "from",
    "to",
)


def _event_row(event: Event) -> dict[str, Any]:
    """One event; decisions and handovers keep their whole data (timings, plans)."""
    data = event.data or {}
    row: dict[str, Any] = {
        "ts": data.get("ts") or event.at.timestamp(),
        "at": _iso(event.at),
        "type": event.kind,
        "drone_id": event.drone.drone_id if event.drone else None,
        "message": event.message,
    }
    for key in _EVENT_FIELDS:
        if data.get(key) is not None:
            row[key] = data[key]
    if event.kind in ("decision", "handover"):
        row["data"] = data
    return row


def _mission_row(mission: Mission) -> dict[str, Any]:
    return {
        "id": str(mission.pk),
        "name": mission.name,
        "organisation": mission.organisation.slug,
        "status": mission.status,
        "altitude": mission.altitude,
        "extensibility": mission.extensibility,
        "created_at": _iso(mission.created_at),
        "started_at": _iso(mission.started_at),
        "ended_at": _iso(mission.ended_at),
    }


def _assignment_row(a: Assignment) -> dict[str, Any]:
    return {
        "id": str(a.pk),
        "drone_id": a.drone.drone_id,
        "reason": a.reason,
        "status": a.status,
        "step_indexes": a.step_indexes,
        "preparation": a.preparation,
        "replaces": str(a.replaces_id) if a.replaces_id else None,
        "decode_ms": a.decode_ms,
        "created_at": _iso(a.created_at),
        "held": a.held,
    }


def _step_row(s: Step) -> dict[str, Any]:
    return {
        "index": s.index,
        "command": s.command,
        "params": s.params,
        "status": s.status,
        "drone_id": s.drone.drone_id if s.drone else None,
        "started_at": _iso(s.started_at),
        "ended_at": _iso(s.ended_at),
        "position": s.position,
        "duration_s": s.duration_s,
    }


def stages(steps: list) -> list[dict]:
    """Time per stage and drone: a stage is a run of steps between two waypoints' arrivals
    (arm, take-off, each navigate with its wait and actions, land)."""
    out: list[dict] = []
    per_drone: dict[str, list] = defaultdict(list)
    for step in steps:
        if step.drone is not None and step.duration_s is not None:
            per_drone[step.drone.drone_id].append(step)
    for drone_id, done in per_drone.items():
        current: dict | None = None
        for step in sorted(done, key=lambda s: (s.started_at or s.ended_at, s.index)):
            starts = step.command in ("arm", "takeoff", "navigate", "land") or current is None
            if starts:
                current = {
                    "drone_id": drone_id,
                    "stage": step.command,
                    "first_index": step.index,
                    "last_index": step.index,
                    "steps": 0,
                    "duration_s": 0.0,
                }
                out.append(current)
            assert current is not None
            current["last_index"] = step.index
            current["steps"] += 1
            current["duration_s"] = round(current["duration_s"] + (step.duration_s or 0.0), 3)
    return out


def parse_log(raw: bytes) -> dict:
    """An uploaded log file → the document, or MissionError saying what is wrong."""
    if len(raw) > MAX_LOG_BYTES:
        raise MissionError("file", f"is larger than {MAX_LOG_BYTES // (1024 * 1024)} MB", 413)
    try:
        doc = json.loads(raw.decode("utf-8"))
    except UnicodeDecodeError:
        raise MissionError("file", "is not UTF-8 text") from None
    except json.JSONDecodeError as exc:
        raise MissionError("file", f"is not JSON ({exc.msg} at line {exc.lineno})") from None
    if not isinstance(doc, dict):
        raise MissionError("file", "must be a JSON object")
    if not isinstance(doc.get("mission"), dict):
        raise MissionError("mission", "is missing: this is not a mission log")
    events = doc.get("events")
    if not isinstance(events, list):
        raise MissionError("events", "must be a list")
    for i, event in enumerate(events):
        if not isinstance(event, dict):
            raise MissionError(f"events[{i}]", "must be an object")
        ts = event.get("ts")
        if isinstance(ts, bool) or not isinstance(ts, int | float):
            raise MissionError(f"events[{i}].ts", "must be a number (seconds since 1970)")
        position = event.get("position")
        if position is not None:
            _check_position(position, f"events[{i}].position")
    for name in ("drones", "assignments", "steps", "stages"):
        if name in doc and not isinstance(doc[name], list):
            raise MissionError(name, "must be a list")
    return doc


def _check_position(position: Any, field: str) -> None:
    if not isinstance(position, dict):
        raise MissionError(field, "must be an object with lat and lon")
    lat, lon = position.get("lat"), position.get("lon")
    for name, value, limit in (("lat", lat, 90), ("lon", lon, 180)):
        if isinstance(value, bool) or not isinstance(value, int | float) or abs(value) > limit:
            raise MissionError(f"{field}.{name}", f"must be a number within ±{limit}")
