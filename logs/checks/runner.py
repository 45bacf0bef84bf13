"""Runs every check on one log's store (the list and order of the health report)."""

from __future__ import annotations

import logging
from collections.abc import Callable

from logs.checks import sensors, vehicle
from logs.checks.base import LogView, Result, not_checked
from logs.checks.thresholds import merged
from logs.store import LogStore

logger = logging.getLogger(__name__)

CHECKS: dict[str, Callable[[LogView, dict], Result]] = {
    "vibration": sensors.vibration,
    "clipping": sensors.clipping,
    "gps": sensors.gps,
    "battery_sag": vehicle.battery_sag,
    "rc_loss": vehicle.rc_loss,
    "motor_imbalance": vehicle.motor_imbalance,
    "estimator": sensors.estimator,
    "failsafe": vehicle.failsafe,
    "cpu_load": vehicle.cpu_load,
    "logging_dropouts": vehicle.logging_dropouts,
}
# Under this much recorded time no check can tell anything (our choice: a second).
MIN_DURATION_S = 1.0


def run_checks(store: LogStore, thresholds: dict | None = None) -> list[dict]:
    """Every check on one log, in CHECKS order, as JSON-ready dicts. `thresholds` is a
    full set (`merged(...)`); the defaults when None. A check that raises is reported
    as not_checked with the error's kind, and the others still run."""
    levels = thresholds or merged()
    view = LogView(store)
    if view.duration < MIN_DURATION_S:
        reason = f"log too short ({max(view.duration, 0.0):.2f} s of records)"
        return [not_checked(name, reason).to_dict() for name in CHECKS]
    results = []
    for name, check in CHECKS.items():
        try:
            result = check(view, levels)
        except Exception as exc:  # noqa: BLE001 - one check's bug must not hide the others
            logger.exception("log check %s failed on %s", name, store.directory)
            result = not_checked(name, f"the check could not read this log ({type(exc).__name__})")
        results.append(result.to_dict())
    return results
