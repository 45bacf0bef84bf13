"""The load test's per-run report: broker rates over the window, runs side by side."""

from __future__ import annotations

import os
import subprocess
import sys
import time

import psutil

from bench.scale_harness import LoadResult, broker_window, compare_runs, waiting_seconds


def test_broker_totals_become_rates_between_refreshes_and_levels_stay_levels():
    # Refreshed every 2 s (10 000 more each time), read every half second.
    readings = [(t / 2, {"messages_received": 1000.0 + 10_000 * ((t + 1) // 4), "ready": t})
                for t in range(12)]  # fmt: skip
    readings[-1][1]["messages_sent"] = 3.0  # seen once: no rate
    assert broker_window(readings) == {"received/s": 5000, "ready": 11, "sent in all": 3}
    assert broker_window([]) == {}


def test_every_run_gets_a_line_with_the_goals_figures():
    runs = []
    for n, lag in enumerate((0.41, 0.93, None), 1):
        r = LoadResult("mosquitto", 1000, 10.0, 20.0, lag_p50_s=0.2, lag_p99_s=lag)
        r.ingest_per_s, r.sent_per_s, r.online = 9990.0 + n, 10000.0, 1000
        r.map_staleness_p99_s, r.cores, r.load_average = 0.5, {"broker": 0.21}, (1.5, 2.25)
        runs.append(r)
    lines = compare_runs(runs).splitlines()
    assert len(lines) == 4 and "lag p50/p99" in lines[0]
    assert "0.20/0.41" in lines[1] and "9991 of 10000" in lines[1] and "0.21" in lines[1]
    assert "0.20/n/a" in lines[3] and "1.5→2.2" in lines[3]


def test_time_spent_waiting_for_a_cpu_is_read_per_role():
    me = {"test": [psutil.Process(os.getpid())]}
    if not waiting_seconds(me):
        return  # no schedstat here (not Linux): the report leaves the line out
    spin = "import time\nend = time.monotonic() + 1.5\nwhile time.monotonic() < end: pass"
    busy = [
        subprocess.Popen([sys.executable, "-c", spin]) for _ in range(3 * (os.cpu_count() or 1))
    ]
    try:
        time.sleep(1.0)
        # Three runnable processes per core: the children (counted with us) must queue.
        assert waiting_seconds(me)["test"] > 0.1
    finally:
        for child in busy:
            child.wait(10)
