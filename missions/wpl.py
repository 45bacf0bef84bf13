"""Plain-text mission files, "QGC WPL 110" (`.waypoints`, `.txt`): what ArduPilot's
Mission Planner saves, and QGroundControl reads and writes beside its `.plan`
[MAVLink file formats].

A header line `QGC WPL 110`, then a mission item a line, tab (or space) separated:
index, current, frame, command, param 1-4, latitude (param 5), longitude (param 6),
altitude (param 7), autocontinue. The file is the mission as the flight controller holds
it, which in ArduPilot starts with item 0, its home. It is read into the `.plan` form
(missions.qgc_plan): item 0 as plannedHomePosition, the rest as simple items of an
ArduPilot plan, so that both files of a mission become the same steps.
"""

from __future__ import annotations

import math

from missions.qgc_plan import QgcPlanError

HEADER = "QGC WPL 110"
COLUMNS = 12
# MAV_AUTOPILOT_ARDUPILOTMEGA: the firmware that writes the format.
FIRMWARE_ARDUPILOT = 3
# A mission of more items than this is not a mission anyone flies (ArduPilot holds at most
# 65 535, an autopilot's storage far fewer); it bounds the work a file can ask for.
MAX_ITEMS = 10_000


def is_wpl(text: str) -> bool:
    return text.lstrip("\ufeff").lstrip().startswith("QGC WPL")


def plan_from_wpl(text: str) -> dict:
    """The `.plan` document a WPL file stands for (QgcPlanError naming the line)."""
    lines = text.lstrip("\ufeff").splitlines()
    if not lines or lines[0].strip() != HEADER:
        raise QgcPlanError("file", f"line 1: expected {HEADER!r}, got {lines[0][:40]!r}")
    rows = [(n, _row(line, n)) for n, line in enumerate(lines[1:], start=2) if line.strip()]
    if len(rows) > MAX_ITEMS:
        raise QgcPlanError("file", f"more than {MAX_ITEMS} mission items")
    if len(rows) < 2 or rows[0][1][0] != 0:
        raise QgcPlanError("file", "needs item 0 (home) and at least one mission item after it")
    for (n, row), expected in zip(rows, range(len(rows)), strict=True):
        if row[0] != expected:
            raise QgcPlanError("file", f"line {n}: item {row[0]:g} where {expected} comes next")
    home = rows[0][1]
    return {
        "fileType": "Plan",
        "version": 1,
        "groundStation": "QGC WPL 110",
        "mission": {
            "version": 2,
            "firmwareType": FIRMWARE_ARDUPILOT,
            "plannedHomePosition": [home[8], home[9], home[10]],
            "items": [_item(row) for _, row in rows[1:]],
        },
        "geoFence": {"version": 2, "polygons": [], "circles": []},
        "rallyPoints": {"version": 2, "points": []},
    }


def _row(line: str, number: int) -> list[float]:
    fields = line.split("\t") if "\t" in line else line.split()
    if len(fields) != COLUMNS:
        raise QgcPlanError("file", f"line {number}: {len(fields)} columns, expected {COLUMNS}")
    try:
        values = [float(v) for v in fields]
    except ValueError:
        raise QgcPlanError("file", f"line {number}: a column is not a number") from None
    if not all(math.isfinite(v) for v in values):
        raise QgcPlanError("file", f"line {number}: a column is not a finite number")
    for column in (0, 2, 3):  # index, frame and command are whole numbers
        if values[column] != int(values[column]):
            raise QgcPlanError("file", f"line {number}: column {column + 1} must be whole")
    return values


def _item(row: list[float]) -> dict:
    return {
        "type": "SimpleItem",
        "doJumpId": int(row[0]),
        "frame": int(row[2]),
        "command": int(row[3]),
        "params": row[4:11],
        "autoContinue": row[11] != 0,
    }


def plan_document(source: str | bytes | dict) -> str | bytes | dict:
    """A `.plan` source as it came, or the `.plan` form of a WPL file's text."""
    if isinstance(source, bytes) and source.lstrip(b"\xef\xbb\xbf \t\r\n").startswith(b"QGC WPL"):
        try:
            source = source.decode("utf-8-sig")
        except UnicodeDecodeError:
            raise QgcPlanError("file", "a QGC WPL file must be UTF-8 text") from None
    if isinstance(source, str) and is_wpl(source):
        return plan_from_wpl(source)
    return source
