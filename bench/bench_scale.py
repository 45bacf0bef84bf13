"""Scale-out: a thousand load drones against the whole ground side, on Mosquitto
and on a two-node RabbitMQ cluster, in the same run.

    .venv/bin/python -m bench.bench_scale [--drones 1000] [--duration 20]

Each run is bench/scale_harness.py's `run_load`: a private broker, the real web (ASGI),
gateway and ingest processes, and N load drones (onboard.loaddrone) at 10 Hz telemetry
and a heartbeat every 5 s. Four runs: 100 drones on Mosquitto (the small-fleet baseline),
1 000 on Mosquitto, then 100 and 1 000 on the RabbitMQ cluster (drones spread over both
nodes, two gateways and two ingests reading the shared AMQP queues). The small cluster run
is kept beside each key (`rabbitmq_small`).

Keys:
- scale.ingest_1000_lag_s: p99 over drones and seconds of how old each drone's newest
  stored sample is, 1 000 drones on Mosquitto (the default broker). Baseline: the same
  with 100 drones, so the ratio is what ten times the fleet costs. The RabbitMQ figure is
  recorded beside it (`rabbitmq`).
- scale.command_rtt_p99_1000: p99 of `POST /api/v1/drones/{id}/commands/` until the
  drone's reply is in the HTTP answer, with the 1 000-drone fleet streaming (Mosquitto).
  Baseline: the same commands to one drone with no fleet connected, in the same run.
- scale.map_staleness_p99: p99 age, on arrival at a `/ws/fleet/` client, of each drone
  update's position (1 000 drones, Mosquitto). Baseline: the same with 100 drones.
- scale.rabbitmq_vs_mosquitto_ingest: rows the ingest stored per second while measured
  (old samples a backlogged broker delivers late count too) on the RabbitMQ cluster, with
  two gateways and two ingests. Baseline: the same on Mosquitto with one of each.

Every run also prints memory per connected drone (ground processes and broker, RSS loaded
minus idle) and samples sent vs stored; they are kept in each key's `runs` detail.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from bench.common import record  # noqa: E402
from bench.scale_harness import LoadConfig, LoadResult, run_load  # noqa: E402


def _figures(result: LoadResult) -> dict:
    """What a key keeps of a run, to read the ratio in context."""
    return {
        "broker": result.broker,
        "drones": result.drones,
        "online": result.online,
        "lag_p50_s": result.lag_p50_s,
        "lag_p99_s": result.lag_p99_s,
        "sent": result.sent,
        "stored": result.stored,
        "lost": result.lost,
        "ingest_per_s": round(result.ingest_per_s, 1),
        "command_rtt_p50_s": result.command_rtt_p50_s,
        "command_rtt_p99_s": result.command_rtt_p99_s,
        "baseline_rtt_p99_s": result.baseline_rtt_p99_s,
        "map_staleness_p99_s": result.map_staleness_p99_s,
        "kib_per_drone": result.kib_per_drone,
        "notes": result.notes,
    }


def _run(config: LoadConfig) -> LoadResult | None:
    began = time.monotonic()
    try:
        result = run_load(config)
    except Exception as exc:  # one broker failing must not lose the other's figures
        print(f"run on {config.broker} with {config.drones} drones failed: {exc}", flush=True)
        return None
    print(result.summary(), flush=True)
    print(f"  ({time.monotonic() - began:.0f} s)", flush=True)
    return result


def _record(key: str, value: float | None, baseline_value: float | None, **figure: object) -> None:
    """Record a key only when both sides were measured; a missing figure is never a 0."""
    if value is None or baseline_value is None:
        print(f"{key}: not recorded (value {value}, baseline {baseline_value})", flush=True)
        return
    record(key, value=value, baseline_value=baseline_value, **figure)  # type: ignore[arg-type]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--drones", type=int, default=1000)
    parser.add_argument("--small", type=int, default=100, help="drones of the baseline run")
    parser.add_argument("--duration", type=float, default=20.0, help="seconds measured per run")
    args = parser.parse_args()
    n = args.drones

    small = _run(LoadConfig(drones=args.small, broker="mosquitto", duration=args.duration))
    mosquitto = _run(LoadConfig(drones=n, broker="mosquitto", duration=args.duration))
    # The cluster with the small fleet too: on a small machine the two RabbitMQ nodes run
    # out of CPU long before 1 000 drones, and this shows where the design itself stands.
    rabbit_small = _run(
        LoadConfig(
            drones=args.small, broker="rabbitmq", duration=args.duration, gateways=2, ingests=2
        )
    )
    rabbit = _run(
        LoadConfig(drones=n, broker="rabbitmq", duration=args.duration, gateways=2, ingests=2)
    )
    runs = {
        "mosquitto_small": None if small is None else _figures(small),
        "mosquitto": None if mosquitto is None else _figures(mosquitto),
        "rabbitmq_small": None if rabbit_small is None else _figures(rabbit_small),
        "rabbitmq": None if rabbit is None else _figures(rabbit),
    }
    if mosquitto is None:
        print("no Mosquitto figures: nothing recorded", flush=True)
        return 1

    if small is not None:
        _record(
            "scale.ingest_1000_lag_s",
            mosquitto.lag_p99_s,
            small.lag_p99_s,
            unit="s",
            baseline_name=f"p99 ingest lag with {args.small} drones",
            higher_is_better=False,
            goal="< 1 s with 1 000 drones at 10 Hz",
            rabbitmq=None if rabbit is None else rabbit.lag_p99_s,
            rabbitmq_small=None if rabbit_small is None else rabbit_small.lag_p99_s,
            runs=runs,
        )
        _record(
            "scale.map_staleness_p99",
            mosquitto.map_staleness_p99_s,
            small.map_staleness_p99_s,
            unit="s",
            baseline_name=f"p99 fleet-map staleness with {args.small} drones",
            higher_is_better=False,
            goal="< 1 s per drone",
            rabbitmq=None if rabbit is None else rabbit.map_staleness_p99_s,
            rabbitmq_small=None if rabbit_small is None else rabbit_small.map_staleness_p99_s,
        )
    _record(
        "scale.command_rtt_p99_1000",
        mosquitto.command_rtt_p99_s,
        mosquitto.baseline_rtt_p99_s,
        unit="s",
        baseline_name="p99 command round trip to one drone, no fleet connected",
        higher_is_better=False,
        goal="a connected fleet barely slows a command",
        rabbitmq=None if rabbit is None else rabbit.command_rtt_p99_s,
        rabbitmq_no_fleet=None if rabbit is None else rabbit.baseline_rtt_p99_s,
        rabbitmq_small=None if rabbit_small is None else rabbit_small.command_rtt_p99_s,
    )
    if rabbit is not None:
        _record(
            "scale.rabbitmq_vs_mosquitto_ingest",
            round(rabbit.ingest_per_s, 1),
            round(mosquitto.ingest_per_s, 1),
            unit="samples/s",
            baseline_name=f"samples stored per second on Mosquitto, {n} drones",
            higher_is_better=True,
            goal=f"the cluster stores what {n} drones send ({n * 10} samples/s)",
            rabbitmq_lost=rabbit.lost,
            mosquitto_lost=mosquitto.lost,
            rabbitmq_small_per_s=None
            if rabbit_small is None
            else round(rabbit_small.ingest_per_s, 1),
            rabbitmq_small_lost=None if rabbit_small is None else rabbit_small.lost,
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
