"""Automatic log checks and spectra on a 100 MB flight log.

Run: .venv/bin/python -m bench.bench_log_checks

- logs.checks_ulog_100mb: every check (logs.checks.run_checks) on the store of a ~100 MB
  PX4 ULog holding every topic the checks read, beside import_to_store of the same file
  in the same run. Goal: at most 2 s.
- logs.checks_ulog_100mb_recomputed: the same when the log lacks vehicle_imu_status, so
  the vibration metric is recomputed from every sensor_combined sample.
- logs.spectrum_100mb: one spectrum request over the whole flight (capped segments)
  beside the same estimate over every segment of the flight.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from bench.common import record
from logs.checks import run_checks
from logs.spectrum import spectrum
from logs.store import import_to_store, open_store

MB = 1 << 20
TARGET = 100 * MB
PROBE_S = 60.0


def _timed(fn) -> tuple[float, object]:
    start = time.perf_counter()
    out = fn()
    return time.perf_counter() - start, out


def _flight(path: Path, **options) -> Path:  # type: ignore[no-untyped-def]
    from logs.synth_faults import px4_ulog

    px4_ulog(path, **options, seconds=PROBE_S)
    seconds = PROBE_S * TARGET / path.stat().st_size
    return px4_ulog(path, **options, seconds=seconds)


def bench_checks(directory: Path, name: str, **options) -> None:  # type: ignore[no-untyped-def]
    path = _flight(directory / f"{name}.ulg", **options)
    import_s, store = _timed(lambda: import_to_store(path, directory / f"{name}-store"))
    # A fresh open, as the import task has: nothing read yet.
    store = open_store(store.directory)
    # The first run is what the import task does right after writing the store.
    runs = [_timed(lambda: run_checks(open_store(store.directory))) for _ in range(3)]
    checks_s, results = runs[0]
    statuses = {r["name"]: r["status"] for r in results}
    record(
        f"logs.{name}",
        value=checks_s,
        unit="s",
        baseline_name="import_to_store of the same file",
        baseline_value=import_s,
        higher_is_better=False,
        goal="<= 2 s for every check",
        file_mb=round(path.stat().st_size / MB, 1),
        flight_s=round(store.index["end"] - store.index["start"], 1),
        best_of_3_s=round(min(r[0] for r in runs), 4),
        statuses=statuses,
    )


def bench_spectrum(directory: Path) -> None:
    path = _flight(directory / "spectrum.ulg")
    store = import_to_store(path, directory / "spectrum-store")
    series = "sensor_combined/accelerometer_m_s2[2]"
    ours, result = _timed(lambda: spectrum(open_store(store.directory), series))
    whole, _ = _timed(
        lambda: spectrum(
            open_store(store.directory), series, max_segments=result.segments_available
        )
    )
    record(
        "logs.spectrum_100mb",
        value=ours,
        unit="s",
        baseline_name=f"the same spectrum of {series} over every segment (no cap)",
        baseline_value=whole,
        higher_is_better=False,
        goal="bounded by the segments read, not the flight's length",
        segments=result.segments,
        segments_available=result.segments_available,
    )


def main() -> None:
    with tempfile.TemporaryDirectory(prefix="bench_log_checks_") as tmp:
        directory = Path(tmp)
        bench_checks(directory, "checks_ulog_100mb", faults={"motor", "gps", "battery"})
        bench_checks(
            directory,
            "checks_ulog_100mb_recomputed",
            topics={
                "vehicle_status",
                "sensor_combined",
                "vehicle_gps_position",
                "battery_status",
                "input_rc",
                "actuator_outputs",
                "estimator_status",
                "cpuload",
            },
        )
        bench_spectrum(directory)


if __name__ == "__main__":
    main()
