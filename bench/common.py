"""Shared helpers for benchmarks: timing and the results file every benchmark updates.

Each figure is written with a baseline measured in the same run, so the ratio holds on a
noisy machine (docs/architecture.md, quality bar).
"""

from __future__ import annotations

import fcntl
import json
import os
import statistics
import time
from collections.abc import Callable
from datetime import UTC, datetime
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results.json"
# The test profile's services, or a test worker's own when PYTEST_XDIST_WORKER names one
# (as config/settings/test.py reads them), so a benchmark can run beside a test run.
_WORKER = os.environ.get("PYTEST_XDIST_WORKER", "")
TEST_PROFILE_ENV = (
    Path(__file__).resolve().parents[1]
    / ".data"
    / (f"test-{_WORKER}" if _WORKER else "test")
    / "env"
)


def test_profile_env() -> dict[str, str]:
    """What scripts/services.sh wrote for the test profile (URLs with their passwords).
    Called once the caller has named its settings module: `config` sets a default."""
    from config.env import data_env_values

    return data_env_values(TEST_PROFILE_ENV)


def record(
    key: str,
    *,
    value: float,
    unit: str,
    baseline_name: str,
    baseline_value: float,
    higher_is_better: bool,
    goal: str,
    **extra: object,
) -> dict:
    """Print one figure with its baseline and merge it into bench/results.json."""
    ratio = value / baseline_value if baseline_value else None
    entry = {
        "value": value,
        "unit": unit,
        "baseline": {"name": baseline_name, "value": baseline_value},
        "ratio": ratio,
        "higher_is_better": higher_is_better,
        "goal": goal,
        "measured_at": datetime.now(UTC).isoformat(timespec="seconds"),
        **extra,
    }
    # Several benchmarks may finish at once: lock, re-read, merge, write.
    with open(RESULTS.with_suffix(".lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        data = json.loads(RESULTS.read_text()) if RESULTS.exists() else {}
        data[key] = entry
        RESULTS.write_text(json.dumps(data, indent=2, sort_keys=True) + "\n")
    ratio_text = f"{ratio:.3g}" if ratio is not None else "n/a"
    print(
        f"{key}: {value:.6g} {unit} (baseline {baseline_name}: {baseline_value:.6g} {unit}, "
        f"ratio {ratio_text}; goal: {goal})",
        flush=True,
    )
    return entry


def best_of(fn: Callable[[], object], *, repeat: int = 5, number: int = 1) -> float:
    """Best wall time in seconds of `number` calls, over `repeat` rounds."""
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        for _ in range(number):
            fn()
        times.append((time.perf_counter() - start) / number)
    return min(times)


def percentile(samples: list[float], q: float) -> float:
    """q in 0..100, nearest-rank on sorted samples."""
    ordered = sorted(samples)
    index = max(0, min(len(ordered) - 1, round(q / 100 * (len(ordered) - 1))))
    return ordered[index]


def median(samples: list[float]) -> float:
    return statistics.median(samples)
