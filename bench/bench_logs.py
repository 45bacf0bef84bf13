"""Flight-log import and level-of-detail benchmarks.

Run: .venv/bin/python -m bench.bench_logs [--bin-slice-mb N]

- logs.import_ulog_100mb: our import_log of a generated ~100 MB ULog vs pyulog's own parse.
- logs.import_ulog_1gb_s / logs.import_ulog_1gb_rss: what the import task runs on a ~1 GB
  ULog (import_to_store: parse and write the columnar store) vs pyulog's parse, each side
  in its own process, with the peak resident memory of each (--skip-1gb leaves them out,
  --only-1gb runs only them; --ulog-1gb-file PATH keeps the generated file there for the
  next run).
- logs.import_bin_100mb: our import_log of a generated ~100 MB ArduPilot .bin vs pymavlink's
  full decode (mavlink_connection + recv_match loop). pymavlink takes tens of seconds per
  100 MB, so with --bin-slice-mb both sides are timed on the first N MB of the same
  generated log and scaled to 100 MB by the same factor.
- logs.bytes_hour_series: JSON bytes of a one-hour 50 Hz series downsampled for a
  1 500-pixel plot vs the JSON of every point.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from pymavlink import mavutil
from pyulog import ULog

from bench.common import record
from logs import import_log
from logs.lod import downsample
from logs.synth import synthetic_dataflash, synthetic_ulog

MB = 1 << 20
TARGET = 100 * MB
# Bytes per second of flight of the synthetic logs (measured once, see _seconds_for).
ULOG_PROBE_S = 20.0


def _seconds_for(writer, directory: Path, target: int) -> float:
    probe = directory / "probe"
    writer(probe, seconds=ULOG_PROBE_S)
    rate = probe.stat().st_size / ULOG_PROBE_S
    probe.unlink()
    return target / rate


def _timed(fn) -> float:
    start = time.perf_counter()
    fn()
    return time.perf_counter() - start


def _pymavlink_decode(path: Path) -> int:
    # pymavlink prints a line per message it cannot file; keep the benchmark output readable.
    with contextlib.redirect_stdout(io.StringIO()):
        conn = mavutil.mavlink_connection(str(path))
        count = 0
        while conn.recv_match() is not None:
            count += 1
    return count


def bench_ulog(directory: Path) -> None:
    path = directory / "big.ulg"
    synthetic_ulog(path, seconds=_seconds_for(synthetic_ulog, directory, TARGET))
    size_mb = path.stat().st_size / MB
    ours = min(_timed(lambda: import_log(path)) for _ in range(2))
    theirs = min(_timed(lambda: ULog(str(path))) for _ in range(2))
    record(
        "logs.import_ulog_100mb",
        value=ours,
        unit="s",
        baseline_name="pyulog ULog(path) parse of the same file",
        baseline_value=theirs,
        higher_is_better=False,
        goal="<= 0.5x pyulog (at least twice as fast), values identical",
        file_mb=round(size_mb, 1),
    )


# Each side runs in a fresh process so its peak resident memory is its own. Ours is the
# import task's own call, its store written to a temporary directory removed after timing.
_CHILD = """
import shutil, sys, tempfile, time
import django
django.setup()
from pathlib import Path
start = time.perf_counter()
if sys.argv[1] == "ours":
    from logs.store import import_to_store
    out = Path(tempfile.mkdtemp(prefix="bench_logs_store_"))
    try:
        import_to_store(Path(sys.argv[2]), out / "store")
        elapsed = time.perf_counter() - start
    finally:
        shutil.rmtree(out)
else:
    from pyulog import ULog
    ULog(sys.argv[2])
    elapsed = time.perf_counter() - start
# VmHWM is this process's own peak (ru_maxrss would carry the parent's across exec).
peak = next(int(l.split()[1]) for l in open("/proc/self/status") if l.startswith("VmHWM:"))
print(elapsed, peak * 1024)
"""


def _in_child(side: str, path: Path) -> tuple[float, int]:
    env = {**os.environ, "DJANGO_SETTINGS_MODULE": "config.settings.test"}
    out = subprocess.run(
        [sys.executable, "-c", _CHILD, side, str(path)],
        check=True,
        capture_output=True,
        text=True,
        env=env,
    ).stdout.split()
    return float(out[-2]), int(out[-1])


def bench_ulog_1gb(directory: Path, keep: Path | None = None) -> None:
    """`keep`: a path where the generated file is kept and reused by the next run (the
    synthetic log is deterministic, so a kept file is the one that would be generated)."""
    path = keep or directory / "huge.ulg"
    if not path.exists():
        synthetic_ulog(path, seconds=_seconds_for(synthetic_ulog, directory, 1024 * MB))
    size = path.stat().st_size
    ours_s, ours_rss = _in_child("ours", path)
    theirs_s, theirs_rss = _in_child("pyulog", path)
    common = {"file_mb": round(size / MB, 1)}
    record(
        "logs.import_ulog_1gb_s",
        value=ours_s,
        unit="s",
        baseline_name="pyulog ULog(path) parse of the same file",
        baseline_value=theirs_s,
        higher_is_better=False,
        goal="<= 0.5x pyulog (ours: import_to_store, the parse and the store written)",
        **common,
    )
    record(
        "logs.import_ulog_1gb_rss",
        value=ours_rss / MB,
        unit="MiB",
        baseline_name="pyulog's peak resident memory on the same file",
        baseline_value=theirs_rss / MB,
        higher_is_better=False,
        goal=(
            "peak resident memory of import_to_store <= 1.0x the file size (the interpreter, "
            "the first pass's record starts, one chunk of the file and one block of records: "
            "each block is written to the store as it is read, never the whole log held)"
        ),
        bound_mib=round(size / MB, 1),
        **common,
    )


def bench_bin(directory: Path, slice_mb: float | None) -> None:
    path = directory / "big.bin"
    synthetic_dataflash(path, seconds=_seconds_for(synthetic_dataflash, directory, TARGET))
    size = path.stat().st_size
    extra = {"file_mb": round(size / MB, 1)}
    measured = path
    if slice_mb:
        # A cut at an arbitrary byte ends in a truncated record, which both readers drop.
        measured = directory / "slice.bin"
        measured.write_bytes(path.read_bytes()[: int(slice_mb * MB)])
        extra["timed_on_mb"] = slice_mb
        extra["note"] = (
            f"both sides timed on the first {slice_mb} MB and scaled by {size / (slice_mb * MB):.2f}"
        )
    scale = size / measured.stat().st_size
    ours = _timed(lambda: import_log(measured)) * scale
    theirs = _timed(lambda: _pymavlink_decode(measured)) * scale
    record(
        "logs.import_bin_100mb",
        value=ours,
        unit="s",
        baseline_name="pymavlink full decode (mavlink_connection + recv_match loop)",
        baseline_value=theirs,
        higher_is_better=False,
        goal=">= 2x faster",
        **extra,
    )


def bench_hour_series() -> None:
    n = 3600 * 50
    t = np.arange(n, dtype=np.int64) * 20_000_000
    rng = np.random.default_rng(3)
    v = np.cumsum(rng.normal(size=n)) * 0.01 + 100.0

    def payload(ts: np.ndarray, vs: np.ndarray) -> int:
        return len(json.dumps({"t": (ts / 1e9).tolist(), "v": vs.tolist()}).encode())

    small_t, small_v = downsample(t, v, 1500)
    record(
        "logs.bytes_hour_series",
        value=payload(small_t, small_v),
        unit="bytes",
        baseline_name="JSON of all 180 000 points",
        baseline_value=payload(t, v),
        higher_is_better=False,
        goal="a few thousand points at most (min/max per pixel: <= 3000)",
        points=len(small_t),
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--bin-slice-mb", type=float, default=None)
    parser.add_argument("--skip-1gb", action="store_true", help="leave out the 1 GB ULog")
    parser.add_argument("--only-1gb", action="store_true", help="run only the 1 GB ULog")
    parser.add_argument(
        "--ulog-1gb-file", type=Path, default=None, help="keep (and reuse) the 1 GB ULog here"
    )
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="bench_logs_") as tmp:
        directory = Path(tmp)
        if args.only_1gb:
            bench_ulog_1gb(directory, args.ulog_1gb_file)
            return
        bench_hour_series()
        bench_ulog(directory)
        if not args.skip_1gb:
            bench_ulog_1gb(directory, args.ulog_1gb_file)
        bench_bin(directory, args.bin_slice_mb)


if __name__ == "__main__":
    main()
