"""Mission decode + queue on the drone, for 45 and 5 000 steps.

[Paula 2018], chapter 5, measured 3.5–6.3 ms on a Raspberry Pi 2. The figure here is
the mission worker's whole intake: base64 → JSON → every step validated → FIFO queue;
the baseline is a plain `json.loads(base64.b64decode(...))` of the same payload, in the
same run, so the ratio is the price of validation.

    .venv/bin/python -m bench.bench_onboard_mission
"""

from __future__ import annotations

import base64
import json

from bench.common import best_of, record
from onboard import protocol
from onboard.mission import decode_mission, queue_steps
from onboard.navigation import ned_to_lla

HOME = (40.6303, -8.6575, 12.0)


def survey_steps(count: int) -> list[dict]:
    """A lawn-mower survey like the Mission Planner's: navigate, wait, sense, takepic."""
    steps = [
        {"index": 0, "command": "arm"},
        {"index": 1, "command": "takeoff", "params": {"altitude": 20}},
    ]
    cycle = ("navigate", "wait_for_flight", "sense", "takepic")
    i = 0
    while len(steps) < count - 2:
        command = cycle[i % len(cycle)]
        params: dict = {}
        if command == "navigate":
            leg = i // len(cycle)
            lat, lon, _ = ned_to_lla((leg % 20) * 10.0, (leg // 20) * 10.0, 0.0, HOME)
            params = {"lat": lat, "lon": lon, "altitude_delta": 0}
        elif command == "wait_for_flight":
            params = {"horizontal_tolerance": 2, "vertical_tolerance": 2}
        elif command == "sense":
            params = {"sensor": "CO2"}
        steps.append({"index": len(steps), "command": command, "params": params})
        i += 1
    steps += [
        {"index": len(steps), "command": "land"},
        {"index": len(steps) + 1, "command": "disarm"},
    ]
    return steps[:count]


def measure(count: int) -> None:
    start = protocol.mission_start("bench", "a1", survey_steps(count))
    payload = start.payload

    def intake() -> None:
        decoded, _ = decode_mission(start)
        queue_steps(decoded)

    def baseline() -> None:
        json.loads(base64.b64decode(payload))

    number = 200 if count < 1000 else 5
    value = best_of(intake, repeat=7, number=number) * 1000
    base = best_of(baseline, repeat=7, number=number) * 1000
    record(
        f"onboard.mission_decode_{count}",
        value=value,
        unit="ms",
        baseline_name="json.loads(base64.b64decode(payload)) without validation",
        baseline_value=base,
        higher_is_better=False,
        goal="below the 3.5-6.3 ms of [Paula 2018] on a Raspberry Pi 2 for a 45-step mission",
        steps=count,
        payload_bytes=len(payload),
    )


def main() -> None:
    for count in (45, 5000):
        measure(count)


if __name__ == "__main__":
    main()
