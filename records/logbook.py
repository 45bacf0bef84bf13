"""Reading flight records: filters, totals by period, CSV rows.

Totals and periods are counted in the portal's time zone (Django's current one), so a
flight at 00:30 local time belongs to the local day and month.
"""

from __future__ import annotations

import csv
import io
import uuid
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass
from datetime import date, datetime, time

from django.db.models import Count, QuerySet, Sum
from django.db.models.functions import TruncMonth, TruncYear
from django.utils import timezone

from fleet.models import DRONE_ID_RE

from .models import FlightRecord

MAX_USERNAME = 150  # Django's username field
PERIODS = {"month": TruncMonth, "year": TruncYear}
FILTERS = ("drone", "pilot", "mission", "since", "until")


class BadFilter(ValueError):
    def __init__(self, field: str, message: str) -> None:
        super().__init__(f"{field}: {message}")
        self.field = field
        self.message = message


def _moment(value: str, field: str, *, end: bool) -> datetime:
    """An ISO date (its start, or for `until` its end) or date-time; naive ones are in the
    portal's time zone."""
    text = value.strip()
    try:
        if len(text) == 10:
            day = date.fromisoformat(text)
            moment = datetime.combine(day, time.max if end else time.min)
        else:
            moment = datetime.fromisoformat(text)
    except ValueError:
        raise BadFilter(field, "must be a date (2026-05-31) or an ISO date-time") from None
    if timezone.is_naive(moment):
        moment = timezone.make_aware(moment, timezone.get_current_timezone())
    return moment


def filtered(records: QuerySet, params: Mapping[str, str]) -> QuerySet:
    """`drone` (drone id), `pilot` (username), `mission` (id), `since`, `until`."""
    if params.get("drone"):
        if not DRONE_ID_RE.match(params["drone"]):
            raise BadFilter("drone", "must be a drone id (letters, digits, _ and -)")
        records = records.filter(drone_ident=params["drone"])
    if params.get("pilot"):
        pilot = params["pilot"]
        if len(pilot) > MAX_USERNAME or "\x00" in pilot:
            raise BadFilter("pilot", f"must be a username (at most {MAX_USERNAME} characters)")
        records = records.filter(pilot_name=pilot)
    if params.get("mission"):
        mission = params["mission"]
        try:
            uuid.UUID(mission)
        except ValueError:
            raise BadFilter("mission", "must be a mission id (a UUID)") from None
        records = records.filter(mission_id=mission)
    if params.get("since"):
        records = records.filter(started_at__gte=_moment(params["since"], "since", end=False))
    if params.get("until"):
        records = records.filter(started_at__lte=_moment(params["until"], "until", end=True))
    return records


@dataclass(frozen=True)
class Total:
    period: datetime | None
    flights: int
    hours: float
    distance_m: float


def totals(records: QuerySet, period: str) -> list[Total]:
    """Flights, hours and distance per period (`month` or `year`), newest first."""
    trunc = PERIODS[period]
    rows = (
        records.order_by()
        .annotate(period=trunc("started_at", tzinfo=timezone.get_current_timezone()))
        .values("period")
        .annotate(flights=Count("id"), seconds=Sum("duration_s"), distance=Sum("distance_m"))
        .order_by("-period")
    )
    return [_total(row["period"], row) for row in rows]


def grand_total(records: QuerySet) -> Total:
    row = records.order_by().aggregate(
        flights=Count("id"), seconds=Sum("duration_s"), distance=Sum("distance_m")
    )
    return _total(None, row)


def _total(period: datetime | None, row: Mapping) -> Total:
    return Total(
        period=period,
        flights=row["flights"] or 0,
        hours=round((row["seconds"] or 0.0) / 3600.0, 3),
        distance_m=round(row["distance"] or 0.0, 1),
    )


CSV_COLUMNS = (
    "id", "drone", "pilot", "origin", "mission", "started_at", "ended_at", "takeoff_at",
    "landing_at", "takeoff_lat", "takeoff_lon", "landing_lat", "landing_lon", "duration_s",
    "airborne_s", "distance_m", "max_height_m", "max_speed_ms", "max_distance_m",
    "battery_start", "battery_end", "energy_wh", "energy_method", "battery", "events",
    "corrects",
)  # fmt: skip


def _local(moment: datetime | None) -> str:
    return timezone.localtime(moment).isoformat() if moment else ""


def _coordinate(position: object, key: str) -> str:
    value = position.get(key) if isinstance(position, dict) else None
    return f"{value:.7f}" if isinstance(value, int | float) else ""


def _number(value: float | None) -> str:
    return "" if value is None else f"{value:g}"


def csv_row(r: FlightRecord) -> list[str]:
    return [
        str(r.pk), _cell(r.drone_ident), _cell(r.pilot_name), r.origin, _cell(r.mission_name),
        _local(r.started_at),
        _local(r.ended_at), _local(r.takeoff_at), _local(r.landing_at),
        _coordinate(r.takeoff_position, "lat"), _coordinate(r.takeoff_position, "lon"),
        _coordinate(r.landing_position, "lat"), _coordinate(r.landing_position, "lon"),
        _number(r.duration_s), _number(r.airborne_s), _number(r.distance_m),
        _number(r.max_height_m), _number(r.max_speed_ms), _number(r.max_distance_m),
        _number(r.battery_start), _number(r.battery_end), _number(r.energy_wh),
        r.energy_method, _cell(r.battery or ""), _cell("; ".join(e.get("message", "") for e in r.events)),
        str(r.corrects_id or ""),
    ]  # fmt: skip


def _cell(text: str) -> str:
    """Text a spreadsheet will not run as a formula (CSV injection)."""
    return "'" + text if text[:1] in ("=", "+", "-", "@") else text


def csv_lines(records: Iterable[FlightRecord]) -> Iterator[str]:
    """The CSV text, a line at a time (streamed)."""
    buffer = io.StringIO()
    writer = csv.writer(buffer)
    for row in [list(CSV_COLUMNS)], map(csv_row, records):
        for values in row:
            writer.writerow(values)
            yield buffer.getvalue()
            buffer.seek(0)
            buffer.truncate()
