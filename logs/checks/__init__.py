"""Automatic checks of a flight log: vibration, clipping, GPS, battery sag, RC loss, motor
balance, estimator, failsafes, processor load and logging gaps.

Plain modules over the columnar store (`logs.store.LogStore`): `run_checks(store)` returns
one result per check, whatever the log's format; a check whose topics the log lacks says
`not_checked` with the reason, never `pass`. Thresholds and their sources are in
`thresholds.py`; docs/log-checks.md describes each check.
"""

from __future__ import annotations

from importlib import import_module

# Names load lazily, as in `logs`: the thresholds (and the settings check that reads
# them when Django starts) need no numpy.
_EXPORTS = {
    "CHECKS": "logs.checks.runner",
    "MIN_DURATION_S": "logs.checks.runner",
    "run_checks": "logs.checks.runner",
    "NOT_CHECKED": "logs.checks.base",
    "STATUSES": "logs.checks.base",
    "Result": "logs.checks.base",
    "DEFAULTS": "logs.checks.thresholds",
    "ThresholdError": "logs.checks.thresholds",
    "merged": "logs.checks.thresholds",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> object:
    if name in _EXPORTS:
        return getattr(import_module(_EXPORTS[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
