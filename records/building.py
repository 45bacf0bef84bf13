"""Opening, closing and recording flights.

The ground learns that a drone armed or disarmed from its heartbeats
(fleet.heartbeats sends `fleet.signals.drones_arming_changed`): arming opens an
`OpenFlight`, disarming marks it. Closing reads the flight's stored telemetry again
(telemetry_sample), so the record is the same whichever process closes it and however
often: a close that ran before is a no-op, and one interrupted leaves the open flight for
the next try (the beat's `records.settle`).
"""

from __future__ import annotations

import json
import logging
from collections.abc import Iterator
from datetime import UTC, datetime, timedelta
from typing import Any

from django.conf import settings
from django.db import IntegrityError, connection, transaction
from django.utils import timezone

from batteries import fitting, usage
from checklists import runs as checklist_runs
from fleet.models import Drone

from . import attribution, figures
from .models import EnergyMethod, FlightRecord, OpenFlight

log = logging.getLogger(__name__)

_SAMPLES_SQL = """
SELECT extract(epoch FROM ts)::float8, object, fields || coalesce(labels, '{}')
FROM telemetry_sample
WHERE drone_id = %s AND object = ANY(%s) AND ts >= %s AND ts <= %s
ORDER BY ts
"""


def heartbeat_state(drone: Drone) -> dict:
    """What the drone's last heartbeat said that a record keeps."""
    return {
        "position": drone.position,
        "battery_remaining": drone.battery_remaining,
        "battery_voltage": drone.battery_voltage,
        "seen": drone.last_seen.isoformat() if drone.last_seen else None,
    }


def open_flight(drone: Drone, at: datetime, mission: dict | None = None) -> OpenFlight | None:
    """A flight in the air for `drone` from `at`; None when one is already open."""
    if OpenFlight.objects.filter(drone=drone, disarmed_at__isnull=True).exists():
        return None
    try:
        with transaction.atomic():
            return OpenFlight.objects.create(
                drone=drone,
                organisation_id=drone.organisation_id,
                armed_at=at,
                mission=mission,
                start={**heartbeat_state(drone), "battery": _battery_serial(drone)},
            )
    except IntegrityError:
        return None  # opened meanwhile by another gateway


def _battery_serial(drone: Drone) -> str | None:
    """The pack the drone carries as it arms (batteries.fitting), by its serial."""
    battery = fitting.carried(drone)
    return None if battery is None else battery.serial


def mark_disarmed(drone: Drone, at: datetime, *, lost: bool = False) -> OpenFlight | None:
    """The drone's open flight, marked disarmed at `at` (None when none is open); `lost`:
    ended because the drone stayed offline while armed."""
    flight = OpenFlight.objects.filter(drone=drone, disarmed_at__isnull=True).first()
    if flight is None:
        return None
    end = {**heartbeat_state(drone), "lost": True} if lost else heartbeat_state(drone)
    updated = OpenFlight.objects.filter(pk=flight.pk, disarmed_at__isnull=True).update(
        disarmed_at=at, end=end
    )
    return flight if updated else None


def reconcile(now: datetime | None = None) -> dict[str, int]:
    """Catch up with the drones' state: open a flight for each armed drone without one,
    mark disarmed the open flights of drones no longer armed, and close every flight
    disarmed long enough ago for its telemetry to be stored."""
    now = now or timezone.now()
    opened = 0
    for drone in Drone.objects.filter(armed=True, online=True, credentials_revoked=False).exclude(
        pk__in=OpenFlight.objects.filter(disarmed_at__isnull=True).values("drone_id")
    ):
        opened += open_flight(drone, drone.last_seen or now, drone.mission) is not None
    marked = 0
    for flight in OpenFlight.objects.filter(disarmed_at__isnull=True, drone__armed=False):
        drone = flight.drone
        marked += mark_disarmed(drone, drone.last_seen or now) is not None
    marked += _end_lost(now)
    settle_before = now - timedelta(seconds=settings.RECORDS_CLOSE_DELAY_S)
    due = OpenFlight.objects.filter(disarmed_at__lte=settle_before).values_list("pk", flat=True)
    closed = sum(close_flight(pk) is not None for pk in list(due))
    return {"opened": opened, "marked": marked, "closed": closed}


def _end_lost(now: datetime) -> int:
    """End at its last heartbeat the flight of a drone offline for RECORDS_LOST_AFTER_S
    while armed: the record says what is known, and that the drone was lost."""
    lost_before = now - timedelta(seconds=settings.RECORDS_LOST_AFTER_S)
    flights = OpenFlight.objects.filter(
        disarmed_at__isnull=True, drone__online=False, drone__last_seen__lt=lost_before
    ).select_related("drone")
    return sum(mark_disarmed(f.drone, f.drone.last_seen, lost=True) is not None for f in flights)


def close_flight(open_flight_pk: int) -> FlightRecord | None:
    """Record the flight and forget the open one, in one transaction; None when it was
    recorded already (or is still in the air)."""
    with transaction.atomic():
        flight = lock_disarmed(open_flight_pk)
        if flight is None:
            return None
        record, found = _record(flight)
        if found is not None:
            usage.take(record, found.resistance_ohm)
        flight.delete()
    log.info("recorded flight %s of %s", record.pk, record.drone_ident)
    return record


def lock_disarmed(open_flight_pk: int) -> OpenFlight | None:
    """The disarmed open flight, locked for this transaction (None when another holds it
    or it is gone). Only its own row is locked, never its drone's: heartbeats go on
    updating the drone while the flight's telemetry is read."""
    return (
        OpenFlight.objects.select_for_update(skip_locked=True, of=("self",))
        .select_related("drone", "organisation")
        .filter(pk=open_flight_pk, disarmed_at__isnull=False)
        .first()
    )


def _record(flight: OpenFlight) -> tuple[FlightRecord, figures.Figures | None]:
    """The flight's record and the figures it was made from (None: recorded before)."""
    margin = timedelta(seconds=settings.RECORDS_WINDOW_MARGIN_S)
    found = _figures(flight, margin)
    started = _at(found.started_at) or flight.armed_at
    ended = _at(found.ended_at) or flight.disarmed_at
    who = attribution.attribute(flight, started)
    energy, method = _energy(flight, found)
    existing = FlightRecord.objects.filter(
        drone_ident=flight.drone.drone_id, started_at=started, corrects__isnull=True
    ).first()
    if existing is not None:
        return existing, None
    record = FlightRecord.objects.create(
        organisation=flight.organisation,
        drone=flight.drone,
        drone_ident=flight.drone.drone_id,
        origin=who.origin,
        pilot=who.pilot,
        pilot_name=who.pilot.get_username() if who.pilot else "",
        mission=who.mission,
        mission_name=who.mission.name if who.mission else "",
        assignment_id=who.assignment_id,
        started_at=started,
        ended_at=ended,
        takeoff_at=_at(found.takeoff_at),
        landing_at=_at(found.landing_at),
        takeoff_position=found.takeoff_position or (flight.start or {}).get("position"),
        landing_position=found.landing_position or (flight.end or {}).get("position"),
        home=(flight.drone.home if isinstance(flight.drone.home, list) else None),
        duration_s=round((ended - started).total_seconds(), 1),
        airborne_s=_airborne(found),
        distance_m=_rounded(found.distance_m),
        max_height_m=_rounded(found.max_height_m),
        max_speed_ms=_rounded(found.max_speed_ms),
        max_distance_m=_rounded(found.max_distance_m),
        battery_start=(flight.start or {}).get("battery_remaining"),
        battery_end=(flight.end or {}).get("battery_remaining"),
        voltage_start=found.voltage_start,
        voltage_end=found.voltage_end,
        energy_wh=_rounded(energy, 3),
        energy_method=method,
        events=_events(flight, started, ended),
        track=found.track,
        samples=found.samples,
        battery=(flight.start or {}).get("battery"),
    )
    return record, found


def _events(flight: OpenFlight, started: datetime, ended: datetime) -> list[dict]:
    found = attribution.events(flight.drone, started, ended)
    # The pre-flight checklist the drone armed on, with its answers and automatic values.
    checked = checklist_runs.flight_event(flight.drone, flight.armed_at)
    if checked is not None:
        found.insert(0, checked)
    if (flight.end or {}).get("lost"):
        found.append(
            {
                "at": ended.isoformat(),
                "kind": "lost",
                "level": "critical",
                "message": "Offline while armed: the record ends at the last heartbeat.",
                "source": f"lost:{flight.drone.drone_id}",
            }
        )
    return found


def _figures(flight: OpenFlight, margin: timedelta) -> figures.Figures:
    acc = figures.Accumulator(flight.armed_at.timestamp(), flight.disarmed_at.timestamp())
    for ts, name, fields in _samples(
        flight.drone_id, flight.armed_at - margin, flight.disarmed_at + margin
    ):
        acc.add(ts, name, fields)
    return acc.result()


def _samples(drone_pk: int, start: datetime, end: datetime) -> Iterator[tuple[float, str, dict]]:
    """The flight's samples in time order, read through a server-side cursor in batches:
    memory stays bounded however long the flight."""
    connection.ensure_connection()
    with connection.connection.cursor(name=f"flight_{drone_pk}") as cursor:
        cursor.itersize = settings.RECORDS_SAMPLE_BATCH
        cursor.execute(_SAMPLES_SQL, (drone_pk, list(figures.OBJECTS), start, end))
        for ts, name, fields in cursor:
            yield ts, name, _fields(fields)


def _fields(value: object) -> dict:
    # Django's connection loads jsonb as text (its JSONField decodes it); plain psycopg as dict.
    if isinstance(value, str):
        value = json.loads(value)
    return value if isinstance(value, dict) else {}


def _energy(flight: OpenFlight, found: figures.Figures) -> tuple[float | None, str]:
    """Energy from power samples when telemetry has voltage and current; else from the
    pack's capacity (gear specs BATTERY.CAPACITY, mAh) times the state-of-charge drop
    times the mean measured voltage."""
    if found.energy_wh is not None:
        return found.energy_wh, EnergyMethod.VOLTAGE_CURRENT
    start, end = flight.start or {}, flight.end or {}
    soc = (start.get("battery_remaining"), end.get("battery_remaining"))
    volts = [
        v
        for v in (found.voltage_start, found.voltage_end)
        + (start.get("battery_voltage"), end.get("battery_voltage"))
        if isinstance(v, int | float)
    ]
    capacity = _capacity_mah(flight.drone.specs)
    if None in soc or capacity is None or not volts:
        return None, EnergyMethod.UNKNOWN
    drop = max(0.0, float(soc[0]) - float(soc[1]))
    return capacity / 1000.0 * drop * (sum(volts) / len(volts)), EnergyMethod.CAPACITY_CHARGE


def _capacity_mah(specs: Any) -> float | None:
    battery = specs.get("BATTERY") if isinstance(specs, dict) else None
    capacity = battery.get("CAPACITY") if isinstance(battery, dict) else None
    try:
        value = float(capacity)
    except (TypeError, ValueError):
        return None
    return value if value > 0 else None


def _at(epoch: float | None) -> datetime | None:
    if epoch is None:
        return None
    return datetime.fromtimestamp(epoch, tz=UTC)


def _airborne(found: figures.Figures) -> float | None:
    if found.takeoff_at is None or found.landing_at is None:
        return None
    return round(found.landing_at - found.takeoff_at, 1)


def _rounded(value: float | None, digits: int = 2) -> float | None:
    return None if value is None else round(value, digits)
