"""Skyhive mission logs (JSON): mission, drones, assignments and a list of events; one
layer per drone with its position and step progress. Extra fields are ignored so the
format can grow."""

from __future__ import annotations

import json
from datetime import datetime
from pathlib import Path

from logs.importers.base import Limits, LogFormatError, Progress, describe
from logs.importers.columns import ColumnCollector
from logs.series import LogData


def _ts_ns(value: object) -> int | None:
    """Event time: Unix seconds (number) or an ISO-8601 string."""
    if isinstance(value, bool):
        return None
    if isinstance(value, int | float):
        return round(value * 1e9)
    if isinstance(value, str):
        try:
            return round(datetime.fromisoformat(value.replace("Z", "+00:00")).timestamp() * 1e9)
        except ValueError:
            return None
    return None


def _number(value: object) -> float | None:
    return float(value) if isinstance(value, int | float) and not isinstance(value, bool) else None


class MissionLogImporter:
    name = "Skyhive mission log"
    extensions = (".json",)

    def sniff(self, path: Path, head: bytes) -> bool:
        text = head.lstrip()
        return text.startswith(b"{") and b'"events"' in head

    def read(self, path: Path, *, limits: Limits, progress: Progress) -> LogData:
        doc = _load(path, limits)
        progress(0.5)
        names = {}
        for drone in doc.get("drones") or []:
            if isinstance(drone, dict) and "id" in drone:
                names[str(drone["id"])] = str(
                    drone.get("name") or drone.get("serial") or drone["id"]
                )
        events = [e for e in doc["events"] if isinstance(e, dict)]
        dropped = len(doc["events"]) - len(events)
        statuses = sorted({str(e["status"]) for e in events if e.get("status") is not None})
        types = sorted({str(e["type"]) for e in events if e.get("type") is not None})
        rows = []
        for event in events:
            t = _ts_ns(event.get("ts"))
            if t is None or event.get("drone_id") is None:
                dropped += 1
                continue
            rows.append((t, event))
        rows.sort(key=lambda r: r[0])
        cols = ColumnCollector()
        for t, event in rows:
            drone = str(event["drone_id"])
            cols.add(f"drone {names.get(drone, drone)}", t, _fields(event, statuses, types))
        for layer in cols.layers:
            cols.units.update(
                {
                    f"{layer}/lat": "deg",
                    f"{layer}/lon": "deg",
                    f"{layer}/alt": "m",
                    f"{layer}/duration": "s",
                }
            )
            cols.labels[f"{layer}/status"] = dict(enumerate(statuses))
            cols.labels[f"{layer}/event"] = dict(enumerate(types))
        log = LogData(format="mission")
        log.metadata = {k: doc[k] for k in ("mission", "drones", "assignments") if k in doc}
        if dropped:
            log.warnings.append(f"Skipped {dropped} events without a drone or a readable time.")
        cols.build(log, "recorder")
        return log


def _load(path: Path, limits: Limits) -> dict:
    """The log's JSON document, refused when too large, unreadable or without events."""
    if path.stat().st_size > limits.max_json_bytes:
        raise LogFormatError(f"The mission log is over the limit of {limits.max_json_bytes} bytes.")
    try:
        doc = json.loads(path.read_bytes())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise LogFormatError(
            f"The mission log is not valid JSON (truncated?): {describe(exc)}."
        ) from exc
    if not isinstance(doc, dict) or not isinstance(doc.get("events"), list):
        raise LogFormatError('The mission log has no "events" list.')
    return doc


def _fields(event: dict, statuses: list[str], types: list[str]) -> dict[str, object]:
    """An event's numeric columns; status and type become indexes into their label lists."""
    fields: dict[str, object] = {}
    position = event.get("position")
    if isinstance(position, dict):
        for key in ("lat", "lon", "alt"):
            number = _number(position.get(key))
            if number is not None:
                fields[key] = number
    if isinstance(event.get("index"), int):
        fields["step index"] = event["index"]
    if event.get("status") is not None:
        fields["status"] = statuses.index(str(event["status"]))
    if event.get("type") is not None:
        fields["event"] = types.index(str(event["type"]))
    number = _number(event.get("duration_s"))
    if number is not None:
        fields["duration"] = number
    return fields
