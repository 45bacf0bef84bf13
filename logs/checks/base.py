"""What every check shares: the result it returns, the severities, and a reader over a
log's columnar store that finds topics by name whatever the format wrote.

A check reads only the store (`logs.store.LogStore`), never the uploaded file, so it runs
the same on a ULog, a DataFlash .bin, a .tlog or any other format whose importer wrote
the topics it looks for. Times in results are seconds since the log's start (the store
index's `start`), the clock the viewer's address uses (`#t=`).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import numpy as np

from logs.store import NS, LogStore

PASS, WARNING, FAIL, NOT_CHECKED = "pass", "warning", "fail", "not_checked"
STATUSES = (PASS, WARNING, FAIL, NOT_CHECKED)
SEVERITY = {NOT_CHECKED: -1, PASS: 0, WARNING: 1, FAIL: 2}


@dataclass
class Result:
    """One check's verdict. `t` is where it shows (seconds since the log's start) or None;
    `series` are the store paths whose plot shows it; `window` the span worth looking at."""

    name: str
    status: str
    value: float | None = None
    unit: str = ""
    threshold: dict[str, float] | None = None
    t: float | None = None
    reason: str = ""
    series: list[str] = field(default_factory=list)
    window: tuple[float, float] | None = None

    def to_dict(self) -> dict:
        return {
            "name": self.name,
            "status": self.status,
            "value": _finite_or_none(self.value),
            "unit": self.unit,
            "threshold": self.threshold,
            "t": _finite_or_none(self.t),
            "reason": self.reason,
            "series": list(self.series),
            "window": list(self.window) if self.window else None,
        }


def _finite_or_none(x: float | None) -> float | None:
    if x is None:
        return None
    x = float(x)
    # Nine significant digits: a float32 figure and its time stamp, without the noise.
    return float(f"{x:.9g}") if math.isfinite(x) else None


def not_checked(name: str, reason: str) -> Result:
    return Result(name, NOT_CHECKED, reason=reason)


def grade(value: float, threshold: dict[str, float], *, higher_is_worse: bool = True) -> str:
    """pass / warning / fail of a figure against {"warning": w, "fail": f}."""
    worse = (lambda v, limit: v > limit) if higher_is_worse else (lambda v, limit: v < limit)
    if "fail" in threshold and worse(value, threshold["fail"]):
        return FAIL
    if "warning" in threshold and worse(value, threshold["warning"]):
        return WARNING
    return PASS


def worst(results: list[Result]) -> Result:
    """The most severe result, the earliest of equals; the others' reasons are appended."""
    ranked = sorted(
        results,
        key=lambda r: (-SEVERITY[r.status], math.inf if r.t is None else r.t),
    )
    first = ranked[0]
    others = [r.reason for r in ranked[1:] if r.reason and r.status != PASS]
    if others:
        first.reason = "; ".join([first.reason, *others])
    return first


class LogView:
    """A store read by topic and field: layers of several instances (`topic_1` from a
    ULog, `VIBE[1]` from a DataFlash log) are found under their topic's name."""

    def __init__(self, store: LogStore) -> None:
        self.store = store
        self.format: str = store.index.get("format", "")
        self.start: float = store.index.get("start") or 0.0
        self.end: float = store.index.get("end") or self.start
        series = store.index["series"]
        self._fields: dict[str, dict[str, str]] = {}
        for path in series:
            layer, _, rest = path.partition("/")
            self._fields.setdefault(layer, {})[rest] = path
        self._armed: tuple[np.ndarray, np.ndarray] | None | bool = False

    @property
    def duration(self) -> float:
        return self.end - self.start

    def instances(self, topic: str) -> list[str]:
        """The layers of `topic`: itself, or its instances in order (topic_0, topic[0]…)."""
        pattern = re.compile(rf"^{re.escape(topic)}(?:_(\d+)|\[(\d+)\])?$")
        found = []
        for layer in self._fields:
            m = pattern.match(layer)
            if m:
                found.append((int(m.group(1) or m.group(2) or -1), layer))
        return [layer for _, layer in sorted(found)]

    def path(self, layer: str, name: str) -> str | None:
        return self._fields.get(layer, {}).get(name)

    def has(self, topic: str, *names: str) -> bool:
        return any(all(self.path(layer, n) for n in names) for layer in self.instances(topic))

    def read(self, path: str) -> tuple[np.ndarray, np.ndarray]:
        """(seconds since the log's start, float64 values) of a numeric series."""
        t_ns, v = self.store.read_ns(path)
        t = np.asarray(t_ns, dtype=np.float64) / NS - self.start
        values = np.asarray(v)
        if values.dtype.kind not in "fiub":
            return t, np.full(len(t), np.nan)
        return t, values.astype(np.float64)

    def labelled(self, path: str, mapping: dict[str, float]) -> tuple[np.ndarray, np.ndarray]:
        """(times, values) of an enumeration read by its labels: a DFI stores text as the
        number of its first appearance, so the same label has a different number in
        each recording; labels not in `mapping` read as NaN."""
        t, v = self.read(path)
        labels = self.store.info(path).get("labels") or {}
        codes = {int(k): mapping.get(label, np.nan) for k, label in labels.items()}
        known = np.isfinite(v) & (v >= 0) & (v <= max(codes, default=-1))
        table = np.full(max(codes, default=-1) + 1, np.nan)
        for code, value in codes.items():
            if code >= 0:
                table[code] = value
        out = np.full(len(v), np.nan)
        out[known] = table[v[known].astype(np.int64)]
        return t, out

    def layers_with(self, *names: str) -> list[str]:
        """The layers that have every one of `names`: a ROS bag's topics are named by
        whoever recorded them, so a message is found by its fields."""
        return [layer for layer, fields in self._fields.items() if all(n in fields for n in names)]

    def unit(self, path: str) -> str:
        return self.store.info(path).get("unit") or ""

    def parameter(self, *names: str) -> float | None:
        """A ULog parameter recorded in the store's metadata, the first of `names` found."""
        params = (self.store.index.get("metadata") or {}).get("parameters") or {}
        for name in names:
            value = params.get(name)
            if isinstance(value, int | float) and math.isfinite(value):
                return float(value)
        # ArduPilot logs its parameters as PARM records, a ground station as PARAM_VALUE.
        for topic, name_f, value_f in (
            ("PARM", "Name", "Value"),
            ("PARAM_VALUE", "param_id", "param_value"),
        ):
            for layer in self.instances(topic):
                np_, vp = self.path(layer, name_f), self.path(layer, value_f)
                if not (np_ and vp):
                    continue
                _, keys = self.store.read_ns(np_)
                _, values = self.store.read_ns(vp)
                keys = np.asarray(keys)
                for name in names:
                    hit = np.flatnonzero(keys == name)
                    if len(hit) and math.isfinite(float(values[hit[-1]])):
                        return float(values[hit[-1]])
        return None

    def autopilot(self) -> str:
        """ "px4", "ardupilot" or "" (the thresholds of some figures depend on who made them)."""
        if self.format == "ulog":
            return "px4"
        if self.format == "dataflash":
            return "ardupilot"
        path = next((self.path(x, "autopilot") for x in self.instances("HEARTBEAT")), None)
        if path:
            _, values = self.read(path)
            # MAV_AUTOPILOT: 3 ArduPilot, 12 PX4 (MAVLink common.xml).
            kinds = set(np.unique(values[np.isfinite(values)]).astype(int).tolist())
            if 3 in kinds:
                return "ardupilot"
            if 12 in kinds:
                return "px4"
        return ""

    def armed(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(times, armed 0/1) from the log's arming record, or None when it has none:
        PX4 vehicle_status.arming_state (2 = armed), ArduPilot EV ids 10/11 (armed,
        disarmed), MAVLink HEARTBEAT.base_mode bit 128 (MAV_MODE_FLAG_SAFETY_ARMED),
        dRonin FlightStatus.Armed ("Armed"; "Arming" is not yet armed)."""
        if self._armed is not False:
            return self._armed  # type: ignore[return-value]
        found: tuple[np.ndarray, np.ndarray] | None = None
        for layer in self.instances("vehicle_status"):
            p = self.path(layer, "arming_state")
            if p:
                t, v = self.read(p)
                found = (t, (v == 2).astype(np.float64))
                break
        if found is None:
            for layer in self.instances("EV"):
                p = self.path(layer, "Id")
                if p:
                    t, v = self.read(p)
                    keep = (v == 10) | (v == 11)
                    if keep.any():
                        found = (t[keep], (v[keep] == 10).astype(np.float64))
                    break
        if found is None:
            for layer in self.instances("HEARTBEAT"):
                p = self.path(layer, "base_mode")
                if p:
                    t, v = self.read(p)
                    found = (t, ((v.astype(np.int64) & 128) > 0).astype(np.float64))
                    break
        if found is None:
            for layer in self.instances("FlightStatus"):
                p = self.path(layer, "Armed")
                if p:
                    t, v = self.labelled(p, {"Disarmed": 0.0, "Arming": 0.0, "Armed": 1.0})
                    keep = np.isfinite(v)
                    found = (t[keep], v[keep])
                    break
        self._armed = found if found is not None and len(found[0]) else None
        return self._armed  # type: ignore[return-value]

    def armed_at(self, t: np.ndarray) -> np.ndarray:
        """Whether the vehicle was armed at each time; all True without an arming record
        or when it never armed (a bench log is checked whole)."""
        armed = self.armed()
        if armed is None or not armed[1].any():
            return np.ones(len(t), dtype=bool)
        at, av = armed
        idx = np.searchsorted(at, t, side="right") - 1
        out = np.zeros(len(t), dtype=bool)
        ok = idx >= 0
        out[ok] = av[idx[ok]] > 0
        return out


def window_around(view: LogView, t: float | None, half: float = 10.0) -> tuple[float, float]:
    """The span to open the viewer on: `half` seconds either side of t, inside the log."""
    if t is None:
        return (0.0, max(view.duration, 0.0))
    lo = max(0.0, t - half)
    hi = min(max(view.duration, t), t + half)
    if hi <= lo:
        hi = lo + 1.0
    return (round(lo, 3), round(hi, 3))
