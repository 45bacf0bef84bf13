"""Logger: a per-flight recording in the DFI format (docs/dfi-format.md).

Every telemetry object type gets its own value file (one toplevelgroup); commands,
responses, mission events, steps, arming events and alarms get theirs. Rows are appended
to CSV files on disk as they come, and description.xml is rewritten whenever the layout
grows, so a crash leaves a readable folder; closing the flight zips it into `<name>.dfi`.

DFI value files hold numbers only, so text becomes an `intEnumeration` whose options are
the texts seen (command names, mission ids, enum labels of flight-controller fields).
"""

from __future__ import annotations

import logging
import math
import re
import shutil
import threading
import time
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO
from xml.sax.saxutils import quoteattr

log = logging.getLogger(__name__)

TIME_UNIT = "microseconds"


@dataclass
class Column:
    kind: str  # "int", "double", "enum", "time"
    name: str
    groups: tuple[str, ...] = ()
    unit: str | None = None
    source: str = "recorder"
    options: dict[str, int] = field(default_factory=dict)

    def format(self, value: Any) -> str:
        if self.kind == "time":
            return str(int(value))
        if self.kind == "enum":
            label = "null" if value is None else str(value)
            if isinstance(value, bool):
                label = "true" if value else "false"
            if label not in self.options:
                self.options[label] = len(self.options)
            return str(self.options[label])
        if self.kind == "int":
            try:
                return str(int(value))
            except (TypeError, ValueError, OverflowError):
                return "0"
        try:
            number = float(value)
        except (TypeError, ValueError):
            return "nan"
        return repr(number) if math.isfinite(number) else "nan"


@dataclass
class Table:
    name: str
    file: str
    columns: list[Column]
    handle: TextIO | None = None
    rows: int = 0


def _safe_file_name(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]", "_", name)[:80] or "object"


def _flatten(fields: dict, groups: tuple[str, ...] = ()) -> list[tuple[tuple[str, ...], str, Any]]:
    """Fields → [(groups, column name, value)]; arrays and nested objects become groups."""
    flat: list[tuple[tuple[str, ...], str, Any]] = []
    for key, value in fields.items():
        if isinstance(value, dict):
            flat.extend(_flatten(value, groups + (str(key),)))
        elif isinstance(value, list | tuple):
            for i, item in enumerate(value):
                flat.append((groups + (str(key),), str(i), item))
        else:
            flat.append((groups, str(key), value))
    return flat


def _kind_of(value: Any) -> str:
    if isinstance(value, bool) or isinstance(value, str) or value is None:
        return "enum"
    if isinstance(value, int):
        return "int"
    return "double"


def _micros(ts: float) -> int:
    return int(round(ts * 1_000_000))


# Fixed layouts of the event files: (kind, name, unit).
EVENT_LAYOUTS: dict[str, list[tuple[str, str, str | None]]] = {
    "commands": [
        ("enum", "direction", None),
        ("enum", "command", None),
        ("enum", "ok", None),
    ],
    "mission": [
        ("enum", "event", None),
        ("enum", "mission", None),
        ("int", "steps", None),
        ("double", "decode", "ms"),
    ],
    "steps": [
        ("enum", "mission", None),
        ("int", "index", None),
        ("enum", "command", None),
        ("enum", "status", None),
        ("double", "latitude", "deg"),
        ("double", "longitude", "deg"),
        ("double", "Altitude", "m"),
        ("double", "duration", "s"),
    ],
    "arming": [
        ("enum", "action", None),
        ("enum", "phase", None),
        ("enum", "armed", None),
    ],
    "alarms": [
        ("enum", "level", None),
        ("enum", "sensor", None),
        ("double", "value", None),
        ("double", "latitude", "deg"),
        ("double", "longitude", "deg"),
        ("double", "Altitude", "m"),
    ],
}


class FlightLog:
    """One flight's recording: a folder of CSV files, zipped by `close()`."""

    def __init__(self, directory: Path) -> None:
        self.directory = directory
        self.directory.mkdir(parents=True, exist_ok=True)
        self.tables: dict[str, Table] = {}
        self._lock = threading.Lock()
        self._layout_dirty = True
        self._last_flush = time.monotonic()
        self.closed = False

    # -- tables ---------------------------------------------------------------------------

    def _table(self, key: str, name: str, columns: list[Column]) -> Table:
        table = self.tables.get(key)
        if table is None:
            file = _safe_file_name(key) + ".csv"
            time_column = Column("time", "time", unit=TIME_UNIT, source="recorder")
            table = Table(name, file, [time_column] + columns)
            table.handle = open(self.directory / file, "a", encoding="utf-8")  # noqa: SIM115
            self.tables[key] = table
            self._layout_dirty = True
        return table

    def _append(self, table: Table, values: list[str]) -> None:
        assert table.handle is not None
        table.handle.write(",".join(values) + "\n")
        table.rows += 1

    def _after_write(self, options_before: int, table: Table) -> None:
        if sum(len(c.options) for c in table.columns) != options_before:
            self._layout_dirty = True
        if self._layout_dirty:
            self._write_description()
        if time.monotonic() - self._last_flush > 1.0:
            self.flush()

    # -- records --------------------------------------------------------------------------

    def telemetry(self, name: str, ts: float, fields: dict) -> None:
        flat = _flatten(fields)
        with self._lock:
            if self.closed:
                return
            key = f"telemetry_{name}"
            table = self.tables.get(key)
            if table is None:
                columns = [Column(_kind_of(v), col, groups) for groups, col, v in flat]
                table = self._table(key, name, columns)
            by_path = {(groups, col): v for groups, col, v in flat}
            before = sum(len(c.options) for c in table.columns)
            values = [str(_micros(ts))]
            for column in table.columns[1:]:
                values.append(column.format(by_path.get((column.groups, column.name))))
            self._append(table, values)
            self._after_write(before, table)

    def event(self, kind: str, values: list[Any], ts: float | None = None) -> None:
        """A row in one of the fixed event files (EVENT_LAYOUTS), values in column order."""
        layout = EVENT_LAYOUTS[kind]
        with self._lock:
            if self.closed:
                return
            table = self._table(kind, kind, [Column(k, n, unit=u) for k, n, u in layout])
            before = sum(len(c.options) for c in table.columns)
            row = [str(_micros(time.time() if ts is None else ts))]
            row += [c.format(v) for c, v in zip(table.columns[1:], values, strict=True)]
            self._append(table, row)
            self._after_write(before, table)

    # -- files ----------------------------------------------------------------------------

    def description_xml(self) -> str:
        lines = ['<?xml version="1.0" encoding="UTF-8"?>', "<recording>"]
        for table in self.tables.values():
            lines.append(
                f"  <toplevelgroup name={quoteattr(table.name)} file={quoteattr(table.file)}"
                ' separator="comma">'
            )
            lines.extend(_column_xml(table.columns))
            lines.append("  </toplevelgroup>")
        lines.append("</recording>")
        return "\n".join(lines) + "\n"

    def _write_description(self) -> None:
        path = self.directory / "description.xml"
        temporary = path.with_suffix(".xml.tmp")
        temporary.write_text(self.description_xml(), encoding="utf-8")
        temporary.replace(path)
        self._layout_dirty = False

    def flush(self) -> None:
        for table in self.tables.values():
            if table.handle is not None:
                table.handle.flush()
        self._last_flush = time.monotonic()

    def close(self) -> Path | None:
        """Zip the flight into `<folder>.dfi` and remove the folder; None when empty."""
        with self._lock:
            if self.closed:
                return None
            self.closed = True
            for table in self.tables.values():
                if table.handle is not None:
                    table.handle.close()
                    table.handle = None
            if not self.tables:
                shutil.rmtree(self.directory, ignore_errors=True)
                return None
            self._write_description()
            archive = self.directory.with_suffix(".dfi")
            partial = archive.with_suffix(".dfi.part")
            with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as zf:
                zf.write(self.directory / "description.xml", "description.xml")
                for table in self.tables.values():
                    zf.write(self.directory / table.file, table.file)
            partial.replace(archive)
            shutil.rmtree(self.directory, ignore_errors=True)
            return archive


def _column_xml(columns: list[Column]) -> list[str]:
    """Column elements in order, with consecutive columns of one group wrapped together."""
    lines: list[str] = []
    open_groups: tuple[str, ...] = ()
    for column in columns:
        common = 0
        while (
            common < min(len(open_groups), len(column.groups))
            and open_groups[common] == column.groups[common]
        ):
            common += 1
        for depth in range(len(open_groups), common, -1):
            lines.append("    " + "  " * depth + "</group>")
        for depth in range(common, len(column.groups)):
            lines.append(
                "    " + "  " * (depth + 1) + f"<group name={quoteattr(column.groups[depth])}>"
            )
        open_groups = column.groups
        indent = "    " + "  " * (len(column.groups) + 1)
        lines.append(indent + _element(column))
    for depth in range(len(open_groups), 0, -1):
        lines.append("    " + "  " * depth + "</group>")
    return lines


def _element(column: Column) -> str:
    if column.kind == "time":
        return f'<time unit="{TIME_UNIT}" source="{column.source}"/>'
    unit = f" unit={quoteattr(column.unit)}" if column.unit else ""
    if column.kind == "enum":
        options = "".join(
            f'<option value="{value}" label={quoteattr(label)}/>'
            for label, value in column.options.items()
        )
        return f"<intEnumeration name={quoteattr(column.name)}>{options}</intEnumeration>"
    tag = "intQuantity" if column.kind == "int" else "doubleQuantity"
    return f"<{tag} name={quoteattr(column.name)}{unit}/>"


class FlightLogger:
    """Keeps the current FlightLog; a new one starts after each landing disarm.

    The agent feeds it telemetry objects and events; `on_state` watches Armed so a flight
    (arm → disarm) ends up in one archive.
    """

    def __init__(self, log_dir: str | Path, drone_id: str) -> None:
        self.log_dir = Path(log_dir)
        self.drone_id = drone_id
        self.archives: list[Path] = []
        self._lock = threading.Lock()
        self._was_armed = False
        self._current = self._new_log()

    def _new_log(self) -> FlightLog:
        stamp = time.strftime("%Y%m%dT%H%M%S", time.gmtime())
        base = self.log_dir / f"{self.drone_id}_{stamp}"
        directory, n = base, 1
        while directory.exists() or directory.with_suffix(".dfi").exists():
            n += 1
            directory = base.with_name(f"{base.name}_{n}")
        return FlightLog(directory)

    @property
    def current(self) -> FlightLog:
        with self._lock:
            return self._current

    def telemetry(self, name: str, ts: float, fields: dict) -> None:
        try:
            self.current.telemetry(name, ts, fields)
        except Exception:  # the logger must never take the agent down
            log.exception("could not log %s", name)

    def event(self, kind: str, details: dict) -> None:
        """An agent event (the kinds the controller and mission worker emit)."""
        try:
            row = _event_row(kind, details)
            if row is not None:
                self.current.event(*row)
        except Exception:
            log.exception("could not log event %s", kind)

    def on_state(self, armed: bool) -> Path | None:
        """Rotate to a new log after a disarm: that flight is complete."""
        with self._lock:
            was, self._was_armed = self._was_armed, armed
            if not (was and not armed):
                return None
            finished, self._current = self._current, self._new_log()
        archive = finished.close()
        if archive is not None:
            self.archives.append(archive)
        return archive

    def close(self) -> Path | None:
        archive = self.current.close()
        if archive is not None:
            self.archives.append(archive)
        return archive


def _position_values(position: Any) -> list[Any]:
    if position is None:
        return [None, None, None]
    if isinstance(position, dict):
        return [position.get("lat"), position.get("lon"), position.get("alt")]
    return [position.lat, position.lon, position.alt]


def _event_row(kind: str, d: dict) -> tuple[str, list[Any]] | None:
    if kind == "command":
        return "commands", ["request", d.get("command"), None]
    if kind == "response":
        return "commands", ["response", d.get("command"), d.get("ok")]
    if kind == "arming":
        return "arming", [d.get("action"), d.get("phase"), d.get("armed")]
    if kind == "mission":
        return "mission", [
            d.get("event"),
            d.get("mission_id"),
            d.get("steps", 0),
            d.get("decode_ms"),
        ]
    if kind == "step":
        return "steps", [
            d.get("mission_id"),
            d.get("index"),
            d.get("command"),
            d.get("event"),
            *_position_values(d.get("position")),
            d.get("duration_s"),
        ]
    if kind == "alarm":
        return "alarms", [
            d.get("level"),
            d.get("sensor"),
            d.get("value"),
            *_position_values(d.get("position")),
        ]
    return None
