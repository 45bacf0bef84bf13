"""What a drone's maintenance owes: each schedule that applies to it and each service
bulletin of its model, measured from the drone's flight records since the task was last
signed off (or since the drone joined the fleet), with its status.

A schedule falls due when any of its triggers is reached: flight hours (the arm-to-disarm
durations of the flight records), flights (one arm/disarm cycle each) or calendar days.
It is due soon once any trigger is within MAINTENANCE_DUE_SOON_FRACTION of its interval.
A bulletin (or a finding on the one drone) is due from its issue until it is signed off
for the drone. Due items
keep the drone on the ground (fleet/airworthiness.py asks `airworthiness_reasons` for many
drones at once: a fixed number of queries however many).
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Iterable, Sequence
from copy import copy
from dataclasses import dataclass, field
from datetime import datetime

from django.conf import settings
from django.contrib.postgres.aggregates import ArrayAgg
from django.db import connection
from django.db.models import Exists, OuterRef, Q, QuerySet, Value
from django.db.models.functions import Lower, Trim
from django.utils import timezone

from fleet.models import Drone
from onboard.gear import sensor_names
from records.models import FlightRecord

from .models import Bulletin, LogEntry, Schedule

OK, DUE_SOON, DUE = "ok", "due_soon", "due"
# How a reason names an item of each kind.
LABELS = {"schedule": "", "bulletin": "service bulletin ", "finding": "finding "}
UNITS = {"hours": "flight hour", "flights": "flight", "days": "day"}


def amount(trigger: str, value: float) -> str:
    """`1 flight`, `12 days`, `0.5 flight hours`: hours to a tenth, the rest whole."""
    shown = f"{value:.1f}".removesuffix(".0") if trigger == "hours" else f"{value:.0f}"
    return f"{shown} {UNITS[trigger]}{'' if shown == '1' else 's'}"


@dataclass(frozen=True)
class Measure:
    trigger: str  # hours, flights or days
    used: float
    limit: float

    @property
    def over(self) -> float:
        return self.used - self.limit

    @property
    def text(self) -> str:
        """`12.5 of 100 flight hours`: what is used of the interval."""
        used = f"{self.used:.1f}" if self.trigger == "hours" else f"{self.used:.0f}"
        return f"{used} of {amount(self.trigger, self.limit)}"

    def to_dict(self) -> dict:
        return {"trigger": self.trigger, "used": round(self.used, 3), "limit": self.limit}


@dataclass(frozen=True)
class Item:
    """One task a drone owes: a schedule's, a bulletin's or a finding's."""

    name: str
    status: str
    since: datetime
    schedule_id: int | None = None
    bulletin_id: int | None = None
    kind: str = "schedule"  # schedule, bulletin or finding
    measures: list[Measure] = field(default_factory=list)

    @property
    def overdue(self) -> str:
        """How far past due, e.g. `overdue by 2.5 flight hours`; a bulletin's date."""
        if self.bulletin_id is not None:
            return f"open since {timezone.localtime(self.since):%Y-%m-%d}"
        past = [m for m in self.measures if m.over >= 0]
        return "; ".join(_overdue_by(m) for m in past) or "not due"

    def to_dict(self) -> dict:
        return {
            "name": self.name,
            "status": self.status,
            "since": self.since.isoformat(),
            "schedule": self.schedule_id,
            "bulletin": self.bulletin_id,
            "kind": self.kind,
            "measures": [m.to_dict() for m in self.measures],
            "overdue": self.overdue if self.status == DUE else "",
        }


def _overdue_by(measure: Measure) -> str:
    if measure.over == 0:
        return f"due now at {amount(measure.trigger, measure.limit)}"
    return f"overdue by {amount(measure.trigger, measure.over)} (interval {measure.limit:g})"


def gear_models(drone: Drone) -> set[str]:
    """The models a drone's gear files name, in lower case: the specs' MODEL and TYPE and
    every sensor's model (onboard gear files, specs.json and sensors.json)."""
    specs = drone.specs if isinstance(drone.specs, dict) else {}
    sensors = drone.sensors if isinstance(drone.sensors, dict) else {}
    named = [specs.get("MODEL"), specs.get("TYPE"), *sensor_names(sensors).values()]
    return {str(name).strip().lower() for name in named if name and str(name).strip()}


def _aimed_at(queryset: QuerySet, drones: Sequence[Drone]) -> QuerySet:
    """The rows of the drones' organisations for one of the drones itself or one of their
    gear models, each with its `model_key` (which drone a row is for is `_each`)."""
    models = set().union(*(gear_models(d) for d in drones))
    return (
        queryset.filter(organisation_id__in={d.organisation_id for d in drones})
        .annotate(model_key=Lower(Trim("model")))
        .filter(
            Q(drone_id__in=[d.pk for d in drones if d.pk is not None])
            | Q(drone__isnull=True, model_key__in=models)
        )
    )


def _each(rows: list, drones: Sequence[Drone]) -> list[list]:
    """The rows from `_aimed_at` that are for each drone, in the rows' order: those on the
    drone itself and those of one of its gear models in its organisation."""
    own: dict[int, list[int]] = defaultdict(list)
    of_model: dict[tuple[int, str], list[int]] = defaultdict(list)
    for n, row in enumerate(rows):
        if row.drone_id is not None:
            own[row.drone_id].append(n)
        else:
            of_model[(row.organisation_id, row.model_key)].append(n)
    out = []
    for drone in drones:
        found = [
            n for n in own.get(drone.pk, []) if rows[n].organisation_id == drone.organisation_id
        ]
        for model in gear_models(drone):
            found += of_model.get((drone.organisation_id, model), [])
        out.append([rows[n] for n in sorted(found)])
    return out


# Per pair of a drone and one of its schedules: `since`, the last sign-off of the schedule
# on the drone, else when the drone joined; and the `seconds` and `flights` of the drone's
# current flight records (those no correction replaced) since then. One statement for
# every pair.
_USAGE_SQL = """
SELECT pair.drone_id, pair.schedule_id, last.since, flown.seconds, flown.flights
FROM unnest(%s::bigint[], %s::bigint[], %s::timestamptz[]) AS pair(drone_id, schedule_id, joined)
CROSS JOIN LATERAL (
    SELECT COALESCE((
        SELECT sign.signed_at FROM {log} AS sign
        WHERE sign.drone_id = pair.drone_id AND sign.schedule_id = pair.schedule_id
        ORDER BY sign.signed_at DESC LIMIT 1
    ), pair.joined) AS since
) AS last
CROSS JOIN LATERAL (
    SELECT SUM(record.duration_s) AS seconds, COUNT(record.id) AS flights
    FROM {records} AS record
    WHERE record.drone_id = pair.drone_id AND record.started_at >= last.since
        AND NOT EXISTS (SELECT 1 FROM {records} AS fix WHERE fix.corrects_id = record.id)
) AS flown
"""


def _usage(pairs: list[tuple[Drone, Schedule]]) -> dict[tuple[int, int], tuple]:
    """(since, seconds, flights) of each stored drone's schedule: one query."""
    stored = [(d, s) for d, s in pairs if d.pk is not None]
    if not stored:
        return {}
    sql = _USAGE_SQL.format(log=LogEntry._meta.db_table, records=FlightRecord._meta.db_table)
    with connection.cursor() as cursor:
        cursor.execute(
            sql,
            [
                [d.pk for d, _ in stored],
                [s.pk for _, s in stored],
                [d.created_at for d, _ in stored],
            ],
        )
        return {(drone, schedule): rest for drone, schedule, *rest in cursor.fetchall()}


def schedules_of(drones: Sequence[Drone]) -> list[list[Schedule]]:
    """Each drone's schedules (in Schedule's order), each a copy annotated with `since`
    (its last sign-off on the drone, else when the drone joined) and the `seconds` and
    `flights` of the drone's current flight records since: two queries for all."""
    if not drones:
        return []
    rows = list(_aimed_at(Schedule.objects.all(), drones))
    mine = _each(rows, drones)
    used = _usage([(d, s) for d, found in zip(drones, mine, strict=True) for s in found])
    return [
        [_annotated(s, *used.get((d.pk, s.pk), (d.created_at, None, None))) for s in found]
        for d, found in zip(drones, mine, strict=True)
    ]


def _annotated(
    schedule: Schedule, since: datetime, seconds: float | None, flights: int | None
) -> Schedule:
    """A copy of the schedule with one drone's usage (a drone not stored has no
    sign-offs and no flight records)."""
    found = copy(schedule)
    found.since, found.seconds, found.flights = since, seconds, flights
    return found


def bulletins_of(drones: Sequence[Drone]) -> list[list[Bulletin]]:
    """Each drone's bulletins of its models and findings on itself that are not signed
    off for it (in Bulletin's order): one query for all."""
    if not drones:
        return []
    stored = [d.pk for d in drones if d.pk is not None]
    rows = list(
        _aimed_at(Bulletin.objects.all(), drones).annotate(
            signed_for=ArrayAgg(
                "sign_offs__drone_id",
                filter=Q(sign_offs__drone_id__in=stored),
                default=Value([]),
            )
        )
    )
    return [
        [b for b in found if d.pk is None or d.pk not in b.signed_for]
        for d, found in zip(drones, _each(rows, drones), strict=True)
    ]


def measures(schedule: Schedule, now: datetime) -> list[Measure]:
    """The triggers of a schedule from `schedules_of` (its annotations)."""
    out = []
    if schedule.every_hours is not None:
        out.append(Measure("hours", (schedule.seconds or 0.0) / 3600.0, schedule.every_hours))
    if schedule.every_flights is not None:
        out.append(Measure("flights", schedule.flights or 0, schedule.every_flights))
    if schedule.every_days is not None:
        days = (now - schedule.since).total_seconds() / 86400.0
        out.append(Measure("days", days, schedule.every_days))
    return out


def status_of(found: Iterable[Measure]) -> str:
    """Due when any trigger is reached; due soon when any is within the margin."""
    found = list(found)
    if any(m.used >= m.limit for m in found):
        return DUE
    margin = settings.MAINTENANCE_DUE_SOON_FRACTION
    if any(m.used >= m.limit * (1.0 - margin) for m in found):
        return DUE_SOON
    return OK


def _schedule_items(schedules: list[Schedule], now: datetime) -> list[Item]:
    found = []
    for schedule in schedules:
        taken = measures(schedule, now)
        found.append(
            Item(
                schedule.name,
                status_of(taken),
                schedule.since,
                schedule_id=schedule.pk,
                measures=taken,
            )
        )
    return found


def _bulletin_items(bulletins: list[Bulletin]) -> list[Item]:
    return [
        Item(
            b.title,
            DUE,
            b.issued_at,
            bulletin_id=b.pk,
            kind="finding" if b.drone_id else "bulletin",
        )
        for b in bulletins
    ]


def items_of(drones: Sequence[Drone], now: datetime | None = None) -> list[list[Item]]:
    """`items` of each drone, in the drones' order: a fixed number of queries for all."""
    now = now or timezone.now()
    schedules = schedules_of(drones)
    bulletins = bulletins_of(drones)
    return [
        _schedule_items(s, now) + _bulletin_items(b)
        for s, b in zip(schedules, bulletins, strict=True)
    ]


def items(drone: Drone, now: datetime | None = None) -> list[Item]:
    """Every task the drone owes, schedules then open bulletins; signed bulletins left out."""
    return items_of([drone], now)[0]


def _reason(owed: list[Item]) -> str | None:
    """`maintenance due: <item> (<how overdue>)` for each due item, or None."""
    due = [item for item in owed if item.status == DUE]
    if not due:
        return None
    named = "; ".join(f"{LABELS[i.kind]}{i.name!r} {i.overdue}" for i in due)
    return f"maintenance due: {named}"


# The annotation a drone looked up with `lookup_reads` carries: False when its
# organisation has no schedule and no open bulletin that could be the drone's (on the
# drone itself, or on a model: its gear is not read in SQL), so it owes nothing.
MAY_OWE = "maintenance_may_owe"


def _could_be_for_drone(queryset: QuerySet) -> QuerySet:
    """Rows of the looked-up drone's organisation on the drone itself or on any model
    (a superset of what `_aimed_at` finds for it)."""
    return queryset.filter(organisation_id=OuterRef("organisation_id")).filter(
        Q(drone_id=OuterRef("pk")) | (Q(drone__isnull=True) & ~Q(model=""))
    )


def lookup_reads() -> dict:
    """`MAY_OWE` as an annotation of a query of drones (the one that finds the drone an
    `arm` is for): whether any schedule or bulletin not signed off for the drone may be
    its. fleet/airworthiness.py adds it to its own (named in settings)."""
    schedules = _could_be_for_drone(Schedule.objects.all())
    bulletins = _could_be_for_drone(Bulletin.objects.all()).exclude(
        Exists(LogEntry.objects.filter(bulletin=OuterRef("pk"), drone=OuterRef(OuterRef("pk"))))
    )
    return {MAY_OWE: Exists(schedules) | Exists(bulletins)}


def airworthiness_reasons(drones: Sequence[Drone]) -> list[str | None]:
    """The maintenance reason of each drone, in the drones' order (fleet/airworthiness.py
    asks it for a selection's candidates or a table page at once). Drones looked up with
    `lookup_reads` that may owe nothing need no query."""
    if all(getattr(d, MAY_OWE, True) is False for d in drones):
        return [None] * len(drones)
    return [_reason(owed) for owed in items_of(drones)]


def fleet_due(organisation: object) -> list[tuple[Drone, list[Item]]]:
    """Each drone of the organisation owing something due or due soon, by drone id."""
    drones = list(Drone.objects.filter(organisation=organisation).order_by("drone_id"))
    out = []
    for drone, found in zip(drones, items_of(drones), strict=True):
        owed = [item for item in found if item.status != OK]
        if owed:
            out.append((drone, owed))
    return out
