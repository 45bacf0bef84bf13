"""The flight controller's parameters recorded in a log, and their differences: between two
logs, or between a log and its organisation's reference set for the drone's model.

What each format records: a PX4 ULog its parameters at the start and those changed in
flight (the file's `P` messages, kept in the store's metadata), an ArduPilot DataFlash log `PARM` records, a
MAVLink .tlog the `PARAM_VALUE` messages a ground station received, and a dRonin/OpenPilot
recording (the agent's DFI) its UAVTalk *settings objects* — those flagged settings in the
object definitions, or named `…Settings` as every dRonin settings object is — as
`Object.Field` with each field's last value. A parameter set later in the log overrides
the earlier value.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from logs.checks.base import LogView
from logs.store import LogStore

# A parameter's value as stored: a number, or an enumeration's option (dRonin).
Value = float | str
# Float parameters are float32 in every format here: equal within its precision.
FLOAT32_REL_TOL = 1e-6
NAMED_RECORDS = (("PARM", "Name", "Value"), ("PARAM_VALUE", "param_id", "param_value"))
AIRFRAME_PARAMETERS = ("SYS_AUTOSTART", "FRAME_CLASS")


@dataclass
class ParameterSet:
    autopilot: str
    airframe: str
    source: str
    values: dict[str, Value]

    def to_dict(self) -> dict:
        return {
            "autopilot": self.autopilot,
            "airframe": self.airframe,
            "source": self.source,
            "count": len(self.values),
            "parameters": self.values,
        }


def read_parameters(store: LogStore) -> ParameterSet:
    """The log's parameters; `values` is empty (and `source` "") when it records none."""
    view = LogView(store)
    for reader in (_ulog, _named_records, _settings_objects):
        found = reader(view)
        if found is not None:
            source, values, autopilot = found
            return ParameterSet(autopilot, _airframe(values), source, values)
    return ParameterSet(view.autopilot(), "", "", {})


def _airframe(values: dict[str, Value]) -> str:
    for name in AIRFRAME_PARAMETERS:
        value = values.get(name)
        if isinstance(value, float) and math.isfinite(value):
            return str(int(value))
    return ""


def _number(value: object) -> Value | None:
    """A finite number; a fraction to float32's 7 significant digits (the formats store
    float32), so 0.135 reads 0.135 and not 0.13500000536."""
    try:
        number = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return None
    if not math.isfinite(number):
        return None
    return number if number.is_integer() else float(f"{number:.7g}")


def _ulog(view: LogView) -> tuple[str, dict[str, Value], str] | None:
    params = (view.store.index.get("metadata") or {}).get("parameters") or {}
    values = {str(k): v for k, v in ((k, _number(v)) for k, v in params.items()) if v is not None}
    return ("ULog parameters", values, "px4") if values else None


def _named_records(view: LogView) -> tuple[str, dict[str, Value], str] | None:
    for topic, name_field, value_field in NAMED_RECORDS:
        values: dict[str, Value] = {}
        for layer in view.instances(topic):
            names_path, values_path = view.path(layer, name_field), view.path(layer, value_field)
            if not (names_path and values_path):
                continue
            _, names = view.store.read_ns(names_path)
            _, numbers = view.store.read_ns(values_path)
            for name, number in zip(
                np.asarray(names).tolist(), np.asarray(numbers).tolist(), strict=True
            ):
                value = _number(number)
                key = _text(name)
                if value is not None and key:
                    values[key] = value
        if values:
            return topic, values, view.autopilot()
    return None


def _text(name: object) -> str:
    if isinstance(name, bytes):
        name = name.split(b"\0", 1)[0].decode("ascii", "replace")
    return str(name).strip("\0 ")


def _settings_objects(view: LogView) -> tuple[str, dict[str, Value], str] | None:
    settings_names = _uavtalk_settings()
    values: dict[str, Value] = {}
    for path in view.store.index["series"]:
        layer, _, field = path.partition("/")
        if not field or not (layer in settings_names or layer.endswith("Settings")):
            continue
        value = _last(view.store, path)
        if value is not None:
            values[f"{layer}.{field.replace('/', '.')}"] = value
    return ("dRonin settings objects", values, "dronin") if values else None


def _uavtalk_settings() -> set[str]:
    from onboard.uavtalk.objects import ObjectRegistry

    return {o.name for o in ObjectRegistry.load() if o.settings}


def _last(store: LogStore, path: str) -> Value | None:
    _, values = store.read_ns(path)
    if not len(values):
        return None
    last = np.asarray(values)[-1].item()
    labels = store.info(path).get("labels") or {}
    label = labels.get(str(last)) if isinstance(last, int) else None
    return label if label is not None else _number(last)


# --- differences ---


def same(a: Value, b: Value) -> bool:
    if isinstance(a, str) or isinstance(b, str):
        return a == b
    return math.isclose(a, b, rel_tol=FLOAT32_REL_TOL, abs_tol=0.0)


def diff(a: dict[str, Value], b: dict[str, Value]) -> list[dict]:
    """Each parameter that differs, by name: `change` is "changed", "only_a" or "only_b"."""
    out = []
    for name in sorted(a.keys() | b.keys()):
        if name not in b:
            out.append({"name": name, "a": a[name], "b": None, "change": "only_a"})
        elif name not in a:
            out.append({"name": name, "a": None, "b": b[name], "change": "only_b"})
        elif not same(a[name], b[name]):
            out.append({"name": name, "a": a[name], "b": b[name], "change": "changed"})
    return out
