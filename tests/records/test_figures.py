"""The one-pass figures of a flight, on samples made by hand (no database)."""

from __future__ import annotations

import math

import pytest

from records.figures import MIN_STEP_M, Accumulator


def _feed(acc: Accumulator, samples: list[tuple[float, str, dict]]) -> None:
    for sample in sorted(samples, key=lambda s: s[0]):
        acc.add(*sample)


def test_flight_status_bounds_the_flight_and_samples_outside_are_left_out():
    acc = Accumulator(opened=100.5, closed=130.5)
    _feed(
        acc,
        [
            (95.0, "PositionActual", {"North": 500.0, "East": 0.0, "Down": -50.0}),
            (100.0, "FlightStatus", {"Armed": "Armed"}),
            (101.0, "PositionActual", {"North": 0.0, "East": 0.0, "Down": -0.1}),
            (110.0, "PositionActual", {"North": 30.0, "East": 40.0, "Down": -12.0}),
            (129.0, "PositionActual", {"North": 30.0, "East": 40.0, "Down": 0.0}),
            (130.0, "FlightStatus", {"Armed": "Disarmed"}),
            (131.0, "PositionActual", {"North": 900.0, "East": 0.0, "Down": -80.0}),
        ],
    )
    out = acc.result()
    assert (out.started_at, out.ended_at) == (100.0, 130.0)
    assert out.max_height_m == 12.0 and out.max_distance_m == 50.0
    assert out.distance_m == 50.0
    assert (out.takeoff_at, out.landing_at) == (110.0, 110.0)


def test_without_flight_status_the_ground_times_bound_it():
    acc = Accumulator(opened=100.0, closed=120.0)
    _feed(
        acc,
        [
            (99.0, "PositionActual", {"North": 0.0, "East": 0.0, "Down": -70.0}),
            (105.0, "PositionActual", {"North": 0.0, "East": 0.0, "Down": -5.0}),
            (121.0, "PositionActual", {"North": 0.0, "East": 0.0, "Down": -90.0}),
        ],
    )
    out = acc.result()
    assert (out.started_at, out.ended_at, out.max_height_m) == (100.0, 120.0, 5.0)


def test_hovering_noise_adds_no_distance():
    acc = Accumulator(opened=0.0, closed=100.0)
    noise = MIN_STEP_M * 0.4
    for i in range(1000):
        angle = i * 2.399  # scattered round the hover point, never MIN_STEP_M from it
        fields = {"North": noise * math.cos(angle), "East": noise * math.sin(angle), "Down": -5}
        acc.add(i * 0.1, "PositionActual", fields)
    assert acc.result().distance_m == 0.0


def test_energy_integrates_power_and_skips_gaps():
    acc = Accumulator(opened=0.0, closed=100.0)
    for t in range(0, 11):  # 10 s at 16 V × 10 A
        acc.add(float(t), "FlightBatteryState", {"Voltage": 16.0, "Current": 10.0})
    for t in range(60, 71):  # a 50 s gap, then 10 s more
        acc.add(float(t), "FlightBatteryState", {"Voltage": 15.0, "Current": 12.0})
    out = acc.result()
    assert out.energy_wh == pytest.approx((160 * 10 + 180 * 10) / 3600)
    assert (out.voltage_start, out.voltage_end) == (16.0, 15.0)


def test_speed_positions_and_bad_values():
    acc = Accumulator(opened=0.0, closed=10.0)
    acc.add(1.0, "VelocityActual", {"North": 3.0, "East": 4.0, "Down": 1.0})
    acc.add(2.0, "VelocityActual", {"North": "x", "East": 4.0})
    acc.add(3.0, "GPSPosition", {"Latitude": 406303000, "Longitude": -86575000})
    acc.add(4.0, "GPSPosition", {"Latitude": 0, "Longitude": 0})  # no fix
    acc.add(5.0, "PositionActual", {"North": True, "East": 0.0, "Down": -3.0})
    out = acc.result()
    assert out.max_speed_ms == 5.0
    assert out.landing_position == {"lat": 40.6303, "lon": -8.6575}
    assert out.max_height_m is None
