"""Flights written as the telemetry ingest stores them (telemetry.storage's COPY), and
records made from them the way the ground makes them (open on arming, mark on
disarming, close)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta

from django.db import connection

from telemetry.storage import Sample, copy_samples

RATE_HZ = 10
CLIMB_S = 10.0
HEIGHT_M = 20.0
SPEED_MS = 5.0
LEGS = ((60.0, 0.0), (0.0, 80.0))  # north, then east, metres
VOLTAGE = 16.0
CURRENT_A = 10.0


@dataclass(frozen=True)
class Flown:
    """What the synthetic flight did, for the assertions."""

    armed: float
    disarmed: float
    distance_m: float
    max_height_m: float
    max_distance_m: float
    max_speed_ms: float
    energy_wh: float


def _path(t: float) -> tuple[float, float, float, float, float]:
    """(north, east, height, speed north, speed east) t seconds after take-off began."""
    if t < CLIMB_S:
        return 0.0, 0.0, HEIGHT_M * t / CLIMB_S, 0.0, 0.0
    t -= CLIMB_S
    north = east = 0.0
    for dn, de in LEGS:
        length = math.hypot(dn, de)
        leg_s = length / SPEED_MS
        if t < leg_s:
            f = t / leg_s
            return north + dn * f, east + de * f, HEIGHT_M, dn / leg_s, de / leg_s
        t -= leg_s
        north, east = north + dn, east + de
    height = max(0.0, HEIGHT_M * (1 - t / CLIMB_S))
    return north, east, height, 0.0, 0.0


def flight_samples(drone_pk: int, armed: float) -> tuple[list[Sample], Flown]:
    """Disarmed for 3 s, armed 2 s on the ground, the flight, 2 s on the ground, disarmed."""
    legs_s = sum(math.hypot(*leg) for leg in LEGS) / SPEED_MS
    flight_s = 2 * CLIMB_S + legs_s
    disarmed = armed + 2.0 + flight_s + 2.0
    samples = [Sample(armed - 3.0, drone_pk, "FlightStatus", {"Armed": "Disarmed"})]
    samples.append(Sample(armed, drone_pk, "FlightStatus", {"Armed": "Armed"}))
    t = armed - 3.0
    while t <= disarmed + 3.0:
        since = t - (armed + 2.0)
        n, e, h, vn, ve = _path(since) if 0 <= since <= flight_s else _rest(since, flight_s)
        samples.append(Sample(t, drone_pk, "PositionActual", {"North": n, "East": e, "Down": -h}))
        samples.append(Sample(t, drone_pk, "VelocityActual", {"North": vn, "East": ve, "Down": 0}))
        if round((t - armed) * RATE_HZ) % RATE_HZ == 0:
            current = CURRENT_A if armed <= t <= disarmed else 0.5
            samples.append(
                Sample(t, drone_pk, "FlightBatteryState", {"Voltage": VOLTAGE, "Current": current})
            )
        t = round(t + 1.0 / RATE_HZ, 6)
    samples.append(Sample(disarmed, drone_pk, "FlightStatus", {"Armed": "Disarmed"}))
    samples.sort(key=lambda s: s.ts)
    flown = Flown(
        armed=armed,
        disarmed=disarmed,
        distance_m=sum(math.hypot(*leg) for leg in LEGS),
        max_height_m=HEIGHT_M,
        max_distance_m=math.hypot(60.0, 80.0),
        max_speed_ms=SPEED_MS,
        energy_wh=VOLTAGE * CURRENT_A * (disarmed - armed) / 3600.0,
    )
    return samples, flown


def _rest(since: float, flight_s: float) -> tuple[float, float, float, float, float]:
    if since < 0:
        return 0.0, 0.0, 0.0, 0.0, 0.0
    n, e, _, _, _ = _path(flight_s)
    return n, e, 0.0, 0.0, 0.0


def store(samples: list[Sample]) -> None:
    """COPY into telemetry_sample on the test's own connection (rolled back with it)."""
    connection.ensure_connection()
    copy_samples(connection.connection, samples)


def at(epoch: float) -> datetime:
    return datetime.fromtimestamp(epoch, UTC)


def fly(drone, armed: float, *, seen_late: float = 0.4):  # type: ignore[no-untyped-def]
    """Store one flight's telemetry and record it as the ground does: the heartbeats see
    arming and disarming `seen_late` seconds after they happen."""
    from records import building

    samples, flown = flight_samples(drone.pk, armed)
    store(samples)
    opened = building.open_flight(drone, at(armed + seen_late))
    assert opened is not None
    building.mark_disarmed(drone, at(flown.disarmed + seen_late))
    record = building.close_flight(opened.pk)
    assert record is not None
    return record, flown


def days_ago(days: float) -> float:
    return (datetime.now(UTC) - timedelta(days=days)).timestamp()
