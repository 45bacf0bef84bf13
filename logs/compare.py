"""Two logs on one time axis: where each took off, and the series both recorded.

Take-off is the first moment the log says the vehicle left the ground: PX4
`vehicle_land_detected.landed` falling to 0, ArduPilot's `EV` 28 (LogEvent NOT_LANDED,
[ArduPilot LogEvent]), MAVLink `EXTENDED_SYS_STATE.landed_state` 2
(MAV_LANDED_STATE_IN_AIR, [MAVLink EXTENDED_SYS_STATE]); without those,
the first arming (PX4 `vehicle_status`, ArduPilot `EV` 10, MAVLink `HEARTBEAT`); without
that, the log's start. Times are seconds since the log's start, the viewer's clock.
"""

from __future__ import annotations

import numpy as np

from logs.checks.base import LogView
from logs.store import LogStore

ARDUPILOT_NOT_LANDED = 28
MAV_LANDED_STATE_IN_AIR = 2
NUMERIC_KINDS = ("int", "double", "enum")


def _first(t: np.ndarray, mask: np.ndarray) -> float | None:
    hits = np.flatnonzero(mask)
    return float(t[hits[0]]) if len(hits) else None


def _first_where(view: LogView, topic: str, field: str, test) -> float | None:  # type: ignore[no-untyped-def]
    """The first time `test(values)` holds in the topic's first layer with that field."""
    for layer in view.instances(topic):
        path = view.path(layer, field)
        if path:
            t, values = view.read(path)
            return _first(t, test(values))
    return None


def _airborne_after_ground(landed: np.ndarray) -> np.ndarray:
    """Airborne after having been on the ground (a log may start in the air)."""
    return np.maximum.accumulate(landed == 1) & (landed == 0)


def _landed_flag(view: LogView) -> float | None:
    return _first_where(view, "vehicle_land_detected", "landed", _airborne_after_ground)


def _ardupilot_event(view: LogView) -> float | None:
    return _first_where(view, "EV", "Id", lambda ids: ids == ARDUPILOT_NOT_LANDED)


def _mavlink_landed_state(view: LogView) -> float | None:
    return _first_where(
        view, "EXTENDED_SYS_STATE", "landed_state", lambda s: s == MAV_LANDED_STATE_IN_AIR
    )


def _arming(view: LogView) -> float | None:
    armed = view.armed()
    if armed is None:
        return None
    t, on = armed
    return _first(t, on > 0)


SOURCES = (
    ("landed flag", _landed_flag),
    ("NOT_LANDED event", _ardupilot_event),
    ("landed state", _mavlink_landed_state),
    ("arming", _arming),
)


def takeoff(store: LogStore) -> dict:
    """{"t": seconds since the log's start, "source": what said so}."""
    view = LogView(store)
    for source, find in SOURCES:
        t = find(view)
        if t is not None:
            return {"t": round(max(t, 0.0), 6), "source": source}
    return {"t": 0.0, "source": "log start"}


def common_series(a: LogStore, b: LogStore) -> list[str]:
    """The numeric series both logs recorded, in the first log's order."""
    theirs = set(b.index["series"])
    return [
        path
        for path, info in a.index["series"].items()
        if path in theirs and info.get("kind") in NUMERIC_KINDS
    ]
