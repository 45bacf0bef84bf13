#!/usr/bin/env python
"""Drive the ground side with N lightweight load drones and print what an operator feels.

    .venv/bin/python scripts/loadtest.py --drones 1000 --broker mosquitto|rabbitmq
        [--duration 30] [--rate 10] [--heartbeat 5] [--gateways 1] [--ingests 1]
        [--per-process 250] [--per-message 1] [--connect-spread 2]
        [--runs 1] [--json results.json]

`--runs N` runs it N times in a row, each from scratch, prints every run's figures as it
ends and then one line per run to compare them.

Everything runs on ports of its own (a private Mosquitto or two-node RabbitMQ cluster, the
test profile's PostgreSQL and Redis with a database and db index of our own, the ground
processes as subprocesses) and is stopped at the end, also on Ctrl-C. See
bench/scale_harness.py for what each figure means.
"""

from __future__ import annotations

import argparse
import json
import signal
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from bench.scale_harness import LoadConfig, compare_runs, run_load  # noqa: E402


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawTextHelpFormatter
    )
    parser.add_argument("--drones", type=int, default=1000)
    parser.add_argument("--broker", choices=("mosquitto", "rabbitmq"), default="mosquitto")
    parser.add_argument("--duration", type=float, default=30.0, help="seconds measured")
    parser.add_argument("--rate", type=float, default=10.0, help="telemetry Hz per drone")
    parser.add_argument("--heartbeat", type=float, default=5.0, help="seconds between beats")
    parser.add_argument("--gateways", type=int, default=1)
    parser.add_argument("--ingests", type=int, default=1)
    parser.add_argument("--webs", type=int, default=1)
    parser.add_argument("--per-process", type=int, default=250, help="load drones per process")
    parser.add_argument(
        "--per-message", type=int, default=1,
        help="samples per telemetry message: one message per period of N / rate s",
    )  # fmt: skip
    parser.add_argument(
        "--connect-spread", type=float, default=2.0,
        help="seconds over which each load process connects its drones",
    )  # fmt: skip
    parser.add_argument("--runs", type=int, default=1, help="consecutive runs, each reported")
    parser.add_argument("--json", type=Path, default=None, help="also write the figures here")
    args = parser.parse_args()
    if args.drones < 1:
        parser.error("--drones must be at least 1")
    if args.runs < 1 or args.per_message < 1:
        parser.error("--runs and --per-message must be at least 1")
    config = LoadConfig(
        drones=args.drones,
        broker=args.broker,
        duration=args.duration,
        rate=args.rate,
        heartbeat=args.heartbeat,
        gateways=args.gateways,
        ingests=args.ingests,
        webs=args.webs,
        per_process=args.per_process,
        per_message=args.per_message,
        connect_spread=args.connect_spread,
    )
    # SIGTERM unwinds like Ctrl-C, so run_load stops everything it started.
    signal.signal(signal.SIGTERM, _interrupt)
    results = []
    try:
        for n in range(args.runs):
            result = run_load(config)
            results.append(result)
            if args.runs > 1:
                print(f"run {n + 1} of {args.runs}:")
            print(result.summary(), flush=True)
    except KeyboardInterrupt:
        print("[loadtest] interrupted; everything it started has been stopped", file=sys.stderr)
        return 130
    if args.runs > 1:
        print(compare_runs(results))
    if args.json is not None:
        data = [r.to_dict() for r in results]
        args.json.write_text(json.dumps(data if args.runs > 1 else data[0], indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
