"""One data model for every flight-log format: series addressed by path, grouped in layers.

A series path is "layer/group/.../name"; the first segment is the top-level group, which is
one timeline layer (one message stream or value file). The group tree is implied by the
paths (`LogData.tree()`), so readers only append series.

Time stamps are int64 nanoseconds on the log's own clock (DFI times are 64-bit integers and
PX4/ArduPilot stamp in microseconds, so nanoseconds keep every source exact); the storage
and API layers convert to float seconds at the edge.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

TimeSource = Literal["recorder", "board"]
Kind = Literal["int", "double", "enum", "time", "text"]

SPECIAL_KEYS = (
    "acceleration",
    "altitude",
    "battery",
    "magnetometer",
    "motors",
    "rotation",
    "velocity",
    "gps",
)


@dataclass
class Series:
    """One recorded quantity: values with their time stamps (same length)."""

    path: str
    values: np.ndarray
    times: np.ndarray  # int64 nanoseconds
    unit: str = ""
    time_source: TimeSource = "recorder"
    kind: Kind = "double"
    labels: dict[int, str] | None = None  # enumerations: integer value -> state name
    # Reader hints, e.g. "altitude" or ("gps.alt", "altitude"); one string or several.
    special: str | tuple[str, ...] | None = None

    def __post_init__(self) -> None:
        if isinstance(self.special, str):
            self.special = (self.special,)
        if len(self.values) != len(self.times):
            raise ValueError(
                f"series {self.path}: {len(self.values)} values, {len(self.times)} times"
            )

    @property
    def name(self) -> str:
        return self.path.rsplit("/", 1)[-1]

    @property
    def layer(self) -> str:
        return self.path.split("/", 1)[0]


@dataclass
class Group:
    """A node of the group tree built from series paths."""

    name: str
    groups: dict[str, Group] = field(default_factory=dict)
    series: dict[str, Series] = field(default_factory=dict)


@dataclass
class LogData:
    """A parsed flight log: every series by path, layers in first-seen order."""

    format: str
    series: dict[str, Series] = field(default_factory=dict)
    metadata: dict[str, object] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)

    def add(self, series: Series) -> None:
        if series.path in self.series:
            raise ValueError(f"duplicate series path {series.path}")
        self.series[series.path] = series

    @property
    def layers(self) -> list[str]:
        return list(dict.fromkeys(s.layer for s in self.series.values()))

    def __iter__(self) -> Iterator[Series]:
        return iter(self.series.values())

    def special_by_layer(self) -> dict[str, dict[str, list[str]]]:
        """find_special per layer, leaving out layers without any."""
        found = {layer: find_special(self, layer=layer) for layer in self.layers}
        return {layer: special for layer, special in found.items() if special}

    def tree(self) -> Group:
        root = Group("")
        for s in self.series.values():
            node = root
            for part in s.path.split("/")[:-1]:
                node = node.groups.setdefault(part, Group(part))
            node.series[s.name] = s
        return root


def join(*parts: str) -> str:
    """A series path from its segments; slashes inside a name would fork the tree."""
    return "/".join(p.replace("/", "_") for p in parts if p != "")


def _norm(name: str) -> str:
    return re.sub(r"[^a-z0-9]", "", name.lower())


# Names of the DFI special quantities ([Procházka 2016]) plus the spellings PX4, ArduPilot, MAVLink
# and ardrone_autonomy use; compared after lower-casing and dropping non-alphanumerics.
_SCALAR_NAMES = {
    "altitude": {"altitude", "alt", "altd", "relativealt", "altrel"},
    "battery": {"batterylevel", "battery", "batterypercent", "batteryremaining", "remaining"},
}
_GROUP_NAMES = {
    "acceleration": {"acceleration", "accel", "acc", "linearacceleration"},
    "magnetometer": {"magnetometerreadings", "magnetometer", "mag"},
    "motors": {"motorpowers", "motors", "motor"},
    "rotation": {"rotation", "attitude", "orientation"},
    "velocity": {"velocity", "vel", "linear"},
}
_AXES = ("x", "y", "z")
_ROTATION_AXES = ("roll", "pitch", "yaw")


def _members_xyz(group: Group, prefix: str = "") -> list[Series] | None:
    by_norm = {_norm(n): s for n, s in group.series.items()}
    found = [by_norm.get(prefix + a) for a in _ROTATION_AXES]
    if all(found):
        return found  # type: ignore[return-value]
    # A planar (x, y) velocity is still a velocity; z joins when recorded.
    found = [by_norm.get(prefix + a) for a in _AXES]
    if found[0] and found[1]:
        return [s for s in found if s]
    return None


def _walk(group: Group) -> Iterator[Group]:
    yield group
    for g in group.groups.values():
        yield from _walk(g)


def find_special(log: LogData, *, layer: str | None = None) -> dict[str, list[str]]:
    """Series paths of the special quantities the dedicated views need (within one layer
    when `layer` is given: a mission log has a GPS track per drone).

    Keys are among SPECIAL_KEYS; x/y/z groups (or roll/pitch/yaw for rotation) list their
    members in axis order, motors every motor in name order, gps [lat, lon] or
    [lat, lon, alt]. Reader hints (`Series.special`) win over name matching; otherwise the
    first match in layer order is taken.
    """
    if layer is not None:
        log = LogData(log.format, {p: s for p, s in log.series.items() if s.layer == layer})
    found: dict[str, list[str]] = {}
    hinted: dict[str, dict[str, str]] = {}
    for s in log:
        for tag in s.special or ():
            key, _, member = tag.partition(".")
            hinted.setdefault(key, {})[member] = s.path
    for key, members in hinted.items():
        order = {"x": 0, "y": 1, "z": 2, "roll": 0, "pitch": 1, "yaw": 2, "lat": 0, "lon": 1}
        found[key] = [
            p for _, p in sorted(members.items(), key=lambda m: (order.get(m[0], 9), m[0]))
        ]

    for group in _walk(log.tree()):
        gname = _norm(group.name)
        for key, names in _GROUP_NAMES.items():
            if key in found or gname not in names:
                continue
            if key == "motors":
                numeric = [s for s in group.series.values() if s.kind != "text"]
                if numeric:
                    found[key] = [s.path for s in sorted(numeric, key=lambda s: _natural(s.name))]
            else:
                members = _members_xyz(group)
                if members:
                    found[key] = [s.path for s in members]
        for name, s in group.series.items():
            n = _norm(name)
            for key, names in _SCALAR_NAMES.items():
                if key not in found and n in names and s.kind in ("int", "double"):
                    found[key] = [s.path]
        if "gps" not in found:
            by_norm = {_norm(n): s for n, s in group.series.items()}
            lat = by_norm.get("lat") or by_norm.get("latitude")
            lon = by_norm.get("lon") or by_norm.get("lng") or by_norm.get("longitude")
            if lat and lon:
                alt = by_norm.get("alt") or by_norm.get("altitude")
                found["gps"] = [lat.path, lon.path] + ([alt.path] if alt else [])
        # Flat messages (ardrone Navdata, PX4 topics) keep axes as prefixed fields: vx, ax...
        for key, prefix in (("velocity", "v"), ("acceleration", "a"), ("magnetometer", "mag")):
            if key not in found:
                members = _members_xyz(group, prefix)
                if members and all(s.kind in ("int", "double") for s in members):
                    found[key] = [s.path for s in members]
    return found


def _natural(name: str) -> tuple:
    return tuple(int(p) if p.isdigit() else p for p in re.split(r"(\d+)", name))
