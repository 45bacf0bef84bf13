"""Scale-out: a thousand load drones against the whole ground side, on Mosquitto
and on a two-node RabbitMQ cluster, in the same run.

    .venv/bin/python -m bench.bench_scale [--drones 1000] [--duration 20] [--per-message 1]

Each run is bench/scale_harness.py's `run_load`: a private broker, the real web (ASGI),
gateway and ingest processes, and N load drones (firmware.loaddrone) at 10 Hz telemetry
and a heartbeat every 5 s. Four main runs: 100 drones on Mosquitto (the small-fleet baseline),
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
- scale.ingest_1000_lag_rabbitmq_s: p99 ingest lag (as above) of the 1 000-drone run on
  the RabbitMQ cluster. Baseline: the 1 000-drone run on Mosquitto of the same bench.

A fifth run repeats the 1 000-drone cluster run with the drones sending five samples a
message (a 0.5 s telemetry period), what the drone side can do for the cluster; it is
kept beside the two cluster keys (`rabbitmq_batched…`).

Every run's detail also keeps samples sent per second, each role's CPU cores busy and
cores' worth of time runnable but waiting for a CPU (a process behind for want of CPU
waits a lot; one held back by something else does not), the broker's own figures over the
measured window (Mosquitto's $SYS rates; RabbitMQ's ingest queue: ready, unacknowledged,
published/s, delivered/s) and the load average. `--per-message N` makes the load drones
send one message per N samples (a telemetry period of N / 10 s), as the agent sends every
object of its period in one message.

Every run also prints memory per connected drone (ground processes and broker, RSS loaded
minus idle) and samples sent vs stored; they are kept in each key's `runs` detail.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from bench.common import record  # noqa: E402
from bench.scale_harness import LoadConfig, LoadResult, run_load  # noqa: E402

# Samples per message of the cluster's batched run: a 0.5 s telemetry period at 10 Hz.
BATCHED_PERIOD_SAMPLES = 5


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
        "sent_per_s": round(result.sent_per_s, 1),
        "per_message": result.per_message,
        "cores": {k: round(v, 2) for k, v in result.cores.items()},
        "cpu_wait": result.cpu_wait,
        "broker_figures": result.broker_figures,
        "load_average": result.load_average,
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


def _measure_all(
    drones: int, small: int, duration: float, per_message: int = 1
) -> dict[str, LoadResult | None]:
    """The four runs, by name; a run that failed is None."""

    def cluster(n: int) -> LoadConfig:
        return LoadConfig(
            drones=n, broker="rabbitmq", duration=duration, gateways=2, ingests=2,
            per_message=per_message,
        )  # fmt: skip

    def mosquitto(n: int) -> LoadConfig:
        return LoadConfig(drones=n, broker="mosquitto", duration=duration, per_message=per_message)

    def batched(config: LoadConfig) -> LoadConfig:
        return replace(config, per_message=max(per_message, BATCHED_PERIOD_SAMPLES))

    return {
        "mosquitto_small": _run(mosquitto(small)),
        "mosquitto": _run(mosquitto(drones)),
        # The cluster with the small fleet too: on a small machine the two RabbitMQ nodes
        # run out of CPU long before 1 000 drones, and this shows where the design stands.
        "rabbitmq_small": _run(cluster(small)),
        "rabbitmq": _run(cluster(drones)),
        # What the drone side can do for the cluster: the same samples, one message per
        # BATCHED_PERIOD_SAMPLES of them (a longer telemetry period, as the protocol allows).
        "rabbitmq_batched": _run(batched(cluster(drones))),
    }


def _of(result: LoadResult | None, name: str) -> object:
    """A figure of a run, None when the run failed."""
    return None if result is None else getattr(result, name)


def _record_against_small(runs: dict[str, LoadResult | None], small_drones: int) -> None:
    """Lag and map staleness with the full fleet, against the small one (Mosquitto)."""
    small, mosquitto = runs["mosquitto_small"], runs["mosquitto"]
    rabbit, rabbit_small = runs["rabbitmq"], runs["rabbitmq_small"]
    if small is None or mosquitto is None:
        return
    _record(
        "scale.ingest_1000_lag_s",
        mosquitto.lag_p99_s,
        small.lag_p99_s,
        unit="s",
        baseline_name=f"p99 ingest lag with {small_drones} drones",
        higher_is_better=False,
        goal="< 1 s with 1 000 drones at 10 Hz",
        rabbitmq=_of(rabbit, "lag_p99_s"),
        rabbitmq_small=_of(rabbit_small, "lag_p99_s"),
        runs={name: None if run is None else _figures(run) for name, run in runs.items()},
    )
    _record(
        "scale.map_staleness_p99",
        mosquitto.map_staleness_p99_s,
        small.map_staleness_p99_s,
        unit="s",
        baseline_name=f"p99 fleet-map staleness with {small_drones} drones",
        higher_is_better=False,
        goal="< 1 s per drone",
        rabbitmq=_of(rabbit, "map_staleness_p99_s"),
        rabbitmq_small=_of(rabbit_small, "map_staleness_p99_s"),
    )


def _record_command_rtt(runs: dict[str, LoadResult | None]) -> None:
    mosquitto, rabbit = runs["mosquitto"], runs["rabbitmq"]
    assert mosquitto is not None
    _record(
        "scale.command_rtt_p99_1000",
        mosquitto.command_rtt_p99_s,
        mosquitto.baseline_rtt_p99_s,
        unit="s",
        baseline_name="p99 command round trip to one drone, no fleet connected",
        higher_is_better=False,
        goal="a connected fleet barely slows a command",
        rabbitmq=_of(rabbit, "command_rtt_p99_s"),
        rabbitmq_no_fleet=_of(rabbit, "baseline_rtt_p99_s"),
        rabbitmq_small=_of(runs["rabbitmq_small"], "command_rtt_p99_s"),
    )


def _record_cluster_ingest(runs: dict[str, LoadResult | None], drones: int) -> None:
    mosquitto, rabbit, rabbit_small = runs["mosquitto"], runs["rabbitmq"], runs["rabbitmq_small"]
    batched = runs["rabbitmq_batched"]
    if rabbit is None or mosquitto is None:
        return
    _record(
        "scale.rabbitmq_vs_mosquitto_ingest",
        round(rabbit.ingest_per_s, 1),
        round(mosquitto.ingest_per_s, 1),
        unit="samples/s",
        baseline_name=f"samples stored per second on Mosquitto, {drones} drones",
        higher_is_better=True,
        goal=f"the cluster stores what {drones} drones send ({drones * 10} samples/s)",
        rabbitmq_lost=rabbit.lost,
        mosquitto_lost=mosquitto.lost,
        rabbitmq_small_per_s=None if rabbit_small is None else round(rabbit_small.ingest_per_s, 1),
        rabbitmq_small_lost=_of(rabbit_small, "lost"),
        rabbitmq_batched_per_s=None if batched is None else round(batched.ingest_per_s, 1),
        rabbitmq_batched_lost=_of(batched, "lost"),
        rabbitmq_batched_per_message=_of(batched, "per_message"),
    )
    _record(
        "scale.ingest_1000_lag_rabbitmq_s",
        rabbit.lag_p99_s,
        mosquitto.lag_p99_s,
        unit="s",
        baseline_name=f"p99 ingest lag on Mosquitto, {drones} drones, same run",
        higher_is_better=False,
        goal=f"< 1 s with {drones} drones at 10 Hz on the two-node cluster",
        rabbitmq=_figures(rabbit),
        rabbitmq_batched=None if batched is None else _figures(batched),
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--drones", type=int, default=1000)
    parser.add_argument("--small", type=int, default=100, help="drones of the baseline run")
    parser.add_argument("--duration", type=float, default=20.0, help="seconds measured per run")
    parser.add_argument(
        "--per-message", type=int, default=1, help="samples per telemetry message (load drones)"
    )
    args = parser.parse_args()
    runs = _measure_all(args.drones, args.small, args.duration, args.per_message)
    if runs["mosquitto"] is None:
        print("no Mosquitto figures: nothing recorded", flush=True)
        return 1
    _record_against_small(runs, args.small)
    _record_command_rtt(runs)
    _record_cluster_ingest(runs, args.drones)
    return 0


if __name__ == "__main__":
    sys.exit(main())
