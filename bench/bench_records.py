"""Flight-record figures: one pass over an hour's flight, against touching each sample.

Run: .venv/bin/python -m bench.bench_records

A flight record is computed when its drone disarms, from every sample of the flight
(records/figures.py). One hour of a drone's telemetry as the agent streams it (position
and velocity at 10 Hz, GPS at 5 Hz, battery at 1 Hz: 97 200 samples) goes through the
accumulator; the baseline, in the same run, is the same samples only walked (each sample
looked at once, nothing computed), the floor of any one-pass computation in Python.
"""

from __future__ import annotations

import math

from bench.common import best_of, record
from records.figures import Accumulator

HOUR_S = 3600.0
RATES_HZ = {"PositionActual": 10, "VelocityActual": 10, "GPSPosition": 5, "FlightBatteryState": 1}


def flight_samples() -> list[tuple[float, str, dict]]:
    """A survey flown back and forth at 20 m for an hour, 5 m/s, legs 200 m long."""
    samples: list[tuple[float, str, dict]] = [(0.0, "FlightStatus", {"Armed": "Armed"})]
    for name, rate in RATES_HZ.items():
        for i in range(int(HOUR_S * rate)):
            t = i / rate
            along = (5.0 * t) % 400.0
            east = along if along <= 200.0 else 400.0 - along
            north = 10.0 * math.floor(5.0 * t / 200.0)
            fields = {
                "PositionActual": {"North": north, "East": east, "Down": -20.0},
                "VelocityActual": {"North": 0.0, "East": 5.0, "Down": 0.0},
                "GPSPosition": {"Latitude": 406303000 + int(north * 90), "Longitude": -86575000},
                "FlightBatteryState": {"Voltage": 16.0 - t / 1200, "Current": 12.0},
            }[name]
            samples.append((t, name, fields))
    samples.sort(key=lambda s: s[0])
    samples.append((HOUR_S, "FlightStatus", {"Armed": "Disarmed"}))
    return samples


def compute(samples: list[tuple[float, str, dict]]) -> None:
    acc = Accumulator(0.0, HOUR_S)
    for sample in samples:
        acc.add(*sample)
    acc.result()


def walk(samples: list[tuple[float, str, dict]]) -> None:
    seen = 0
    for _ts, _name, fields in samples:
        seen += len(fields)


def main() -> None:
    samples = flight_samples()
    seconds = best_of(lambda: compute(samples), repeat=3)
    floor = best_of(lambda: walk(samples), repeat=3)
    record(
        "records.figures_one_hour_flight",
        value=seconds,
        unit="s",
        baseline_name="walking the same samples",
        baseline_value=floor,
        higher_is_better=False,
        goal="an hour's flight (97 200 samples) computed in under 1 s",
        samples=len(samples),
    )


if __name__ == "__main__":
    main()
