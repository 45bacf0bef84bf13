"""A drone's flight logs over time: each check's figure across its logs, and whether the
newest one drifts from the drone's own history or from the rest of the fleet.

The statistic: a figure is *drifting* when it lies beyond mean ± k·s of a reference set
on the worse side, where s is the sample standard deviation (n − 1) and k is
settings.LOGS_TREND_SIGMAS (3). The reference is the drone's previous
settings.LOGS_TREND_HISTORY flights (judged once it has LOGS_TREND_MIN_HISTORY of them),
or the latest LOGS_TREND_HISTORY flights of each other drone of the organisation, pooled
(judged when at least FLEET_MIN_DRONES other drones have LOGS_TREND_MIN_HISTORY figures
between them). Three standard deviations is the Shewhart control chart's limit
([Montgomery SQC]). Only figures of the same unit are compared (the `gps` check reports
an outage in s, satellites or HDOP, whichever was worst).

Figures are copied from each log's health report into `LogFigure` when the report is
made, so a trend is one indexed query (bench/bench_log_trends.py).
"""

from __future__ import annotations

import logging
import math
import statistics
from collections import defaultdict
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from datetime import datetime

from django.conf import settings
from django.db import transaction
from django.db.models import F
from django.db.models.functions import Coalesce
from django.utils.module_loading import import_string

from fleet.models import Drone, Organisation
from logs.checks.base import NOT_CHECKED
from logs.events import figure_drifted
from logs.models import FlightLog, LogFigure, LogStatus

logger = logging.getLogger(__name__)

# Below this many other drones a fleet is no reference (one other drone is its history).
FLEET_MIN_DRONES = 2
# Figures where a lower value is the worse one: the lowest cell voltage, the fewest
# satellites. Every other figure (vibration, clips, seconds lost, spread, ratio, load,
# gap) is worse when higher.
LOWER_IS_WORSE = {("battery_sag", "V"), ("gps", "satellites")}
# Figures are float32 readings kept to nine significant digits: a difference under
# float32's resolution (2⁻²³ ≈ 1.2e-7, relative) is no difference, so a constant figure
# (zero spread) never drifts by rounding alone.
RESOLUTION = 1.2e-7
# A log is placed in its drone's history by when it flew, else by when it was uploaded.
FLOWN = Coalesce(F("log__flown_at"), F("log__created_at"))


@dataclass(frozen=True)
class Point:
    log: str
    at: datetime
    value: float | None
    unit: str
    status: str

    def to_dict(self) -> dict:
        return {
            "log": self.log,
            "at": self.at.isoformat(),
            "value": self.value,
            "unit": self.unit,
            "status": self.status,
        }


@dataclass(frozen=True)
class Drift:
    """A figure beyond mean ± sigmas·std of `n` reference figures (`basis`: "own" or "fleet")."""

    basis: str
    value: float
    mean: float
    std: float
    limit: float
    n: int
    sigmas: float

    def to_dict(self) -> dict:
        return {
            "basis": self.basis,
            "value": self.value,
            "mean": self.mean,
            "std": self.std,
            "limit": self.limit,
            "n": self.n,
            "sigmas": self.sigmas,
        }

    def describe(self, check: str, unit: str) -> str:
        against = "its previous" if self.basis == "own" else "the fleet's latest"
        return (
            f"{check} {self.value:.4g} {unit} is beyond {self.limit:.4g} {unit}, the mean "
            f"{self.mean:.4g} ± {self.sigmas:g} standard deviations ({self.std:.3g}) of "
            f"{against} {self.n} flights"
        )


def lower_is_worse(check: str, unit: str) -> bool:
    return (check, unit) in LOWER_IS_WORSE


def drift(
    value: float,
    reference: Sequence[float],
    *,
    basis: str,
    lower_worse: bool = False,
    sigmas: float | None = None,
    min_history: int | None = None,
) -> Drift | None:
    """The drift of `value` from `reference`, or None when it is within the band or the
    reference holds fewer than `min_history` figures."""
    sigmas = float(settings.LOGS_TREND_SIGMAS if sigmas is None else sigmas)
    min_history = int(settings.LOGS_TREND_MIN_HISTORY if min_history is None else min_history)
    if len(reference) < max(min_history, 2) or not math.isfinite(value):
        return None
    mean = statistics.fmean(reference)
    std = statistics.stdev(reference)
    limit = mean - sigmas * std if lower_worse else mean + sigmas * std
    margin = RESOLUTION * max(abs(limit), abs(value))
    beyond = value < limit - margin if lower_worse else value > limit + margin
    if not beyond:
        return None
    return Drift(basis, value, mean, std, limit, len(reference), sigmas)


# --- keeping figures ---


def record(log: FlightLog, checks: Iterable[dict]) -> None:
    """Keep the report's figures for the trends, replacing any earlier ones of this log."""
    rows = [
        LogFigure(
            log=log,
            name=c["name"],
            status=c["status"],
            value=c.get("value"),
            unit=(c.get("unit") or "")[:16],
        )
        for c in checks
    ]
    with transaction.atomic():
        LogFigure.objects.filter(log=log).delete()
        LogFigure.objects.bulk_create(rows)


def _points(rows: Iterable[tuple]) -> list[Point]:
    return [
        Point(str(log_id), at, value, unit, status)
        for log_id, at, value, unit, status in rows
        if value is not None and status != NOT_CHECKED
    ]


def _figures(organisation: Organisation, check: str):  # type: ignore[no-untyped-def]
    return LogFigure.objects.filter(
        name=check, log__organisation=organisation, log__status=LogStatus.READY
    ).annotate(flown=FLOWN)


# --- one drone ---


def history(drone: Drone, check: str) -> list[Point]:
    """The drone's figures of one check, oldest first."""
    rows = (
        _figures(drone.organisation, check)
        .filter(log__drone=drone)
        .order_by("flown", "log_id")
        .values_list("log_id", "flown", "value", "unit", "status")
    )
    return _points(rows)


def fleet_reference(
    organisation: Organisation, check: str, unit: str, *, excluding: int
) -> tuple[list[float], int]:
    """The latest LOGS_TREND_HISTORY figures (of `unit`) of each other drone, pooled,
    and how many drones gave them."""
    keep = int(settings.LOGS_TREND_HISTORY)
    rows = (
        _figures(organisation, check)
        .filter(log__drone__isnull=False, unit=unit, value__isnull=False)
        .exclude(log__drone_id=excluding)
        .exclude(status=NOT_CHECKED)
        .order_by("log__drone_id", "-flown")
        .values_list("log__drone_id", "value")
    )
    per_drone: dict[int, list[float]] = defaultdict(list)
    for drone_id, value in rows:
        if len(per_drone[drone_id]) < keep:
            per_drone[drone_id].append(value)
    return [v for values in per_drone.values() for v in values], len(per_drone)


def judge(points: Sequence[Point], check: str, fleet: tuple[list[float], int]) -> list[Drift]:
    """Whether the newest of `points` drifts from the ones before it, and from the fleet."""
    if not points:
        return []
    newest = points[-1]
    worse_low = lower_is_worse(check, newest.unit)
    keep = int(settings.LOGS_TREND_HISTORY)
    own = [p.value for p in points[:-1] if p.unit == newest.unit][-keep:]
    found = [drift(newest.value, own, basis="own", lower_worse=worse_low)]  # type: ignore[arg-type]
    values, drones = fleet
    if drones >= FLEET_MIN_DRONES:
        found.append(drift(newest.value, values, basis="fleet", lower_worse=worse_low))  # type: ignore[arg-type]
    return [d for d in found if d is not None]


def drone_trend(drone: Drone, checks: Iterable[str]) -> dict:
    """Each check's figures over the drone's logs, and the newest one's drifts."""
    out = {}
    for check in checks:
        points = history(drone, check)
        fleet = (
            fleet_reference(drone.organisation, check, points[-1].unit, excluding=drone.pk)
            if points
            else ([], 0)
        )
        out[check] = {
            "points": [p.to_dict() for p in points],
            "drift": [d.to_dict() for d in judge(points, check, fleet)],
        }
    return out


# --- the fleet ---


def fleet_trend(organisation: Organisation, check: str) -> list[dict]:
    """Every drone's figures of one check, oldest first, with its newest figure's
    drifts: one query over the kept figures, the statistics in memory."""
    keep = int(settings.LOGS_TREND_HISTORY)
    rows = (
        _figures(organisation, check)
        .filter(log__drone__isnull=False)
        .order_by("log__drone_id", "flown", "log_id")
        .values_list(
            "log__drone_id", "log__drone__drone_id", "log_id", "flown", "value", "unit", "status"
        )
    )
    by_drone: dict[tuple[int, str], list[tuple]] = defaultdict(list)
    for pk, ident, *rest in rows:
        by_drone[(pk, ident)].append(tuple(rest))
    points = {key: _points(found) for key, found in by_drone.items()}
    latest = {
        key: [p for p in found if found and p.unit == found[-1].unit][-keep:]
        for key, found in points.items()
    }
    out = []
    for key, found in points.items():
        unit = found[-1].unit if found else ""
        others = [
            p.value
            for other, values in latest.items()
            if other != key
            for p in values
            if p.unit == unit
        ]
        donors = sum(1 for other, values in latest.items() if other != key and values)
        out.append(
            {
                "drone": key[1],
                "points": [p.to_dict() for p in found],
                "drift": [d.to_dict() for d in judge(found, check, (others, donors))],  # type: ignore[misc]
            }
        )
    return out


# --- acting on a drift ---


def evaluate(log: FlightLog) -> list[Drift]:
    """After a log of a drone is checked: when it is the drone's newest, judge each of its
    figures and raise a warning alert (and, where the organisation wants one, a
    maintenance item) for each drift. Once per log and check, however often it runs."""
    drone = log.drone
    if drone is None or log.status != LogStatus.READY:
        return []
    newest = (
        FlightLog.objects.filter(drone=drone, status=LogStatus.READY)
        .annotate(flown=Coalesce(F("flown_at"), F("created_at")))
        .order_by("-flown", "-pk")
        .values_list("pk", flat=True)
        .first()
    )
    if newest != log.pk:
        return []
    found = []
    for figure in log.figures.exclude(status=NOT_CHECKED).exclude(value__isnull=True):
        points = history(drone, figure.name)
        fleet = fleet_reference(log.organisation, figure.name, figure.unit, excluding=drone.pk)
        for d in judge(points, figure.name, fleet):
            found.append(d)
            _act(log, figure, d)
    return found


def _act(log: FlightLog, figure: LogFigure, found: Drift) -> None:
    """Tell the platform (an alert, logs.events); where the organisation wants one, and
    the drift is new, open a maintenance item on the drone."""
    drone = log.drone
    assert drone is not None
    title = f"{drone.drone_id}: {figure.name} drifting from {_basis(found)}"
    detail = f"{found.describe(figure.name, figure.unit)}; log {log.name}"
    source = f"log-trend:{log.pk}:{figure.name}:{found.basis}"
    answers = figure_drifted.send(
        sender=FlightLog,
        log=log,
        drone=drone,
        check=figure.name,
        title=title,
        detail=detail,
        source=source,
    )
    if any(answer for _, answer in answers) and wants_maintenance(log.organisation):
        open_maintenance(drone, title, detail, source)


def _basis(found: Drift) -> str:
    return "its own history" if found.basis == "own" else "the fleet"


def wants_maintenance(organisation: Organisation) -> bool:
    chosen = set(settings.LOGS_TREND_MAINTENANCE or [])
    return "*" in chosen or organisation.slug in chosen


def open_maintenance(drone: Drone, title: str, detail: str, source: str) -> None:
    """Open a maintenance item on the drone through settings.LOGS_TREND_MAINTENANCE_FUNCTION
    (a dotted path called with drone, title, detail and source); none is opened while it
    is empty."""
    path = settings.LOGS_TREND_MAINTENANCE_FUNCTION
    if not path:
        logger.warning("no maintenance function is set: %s is not opened on %s", title, drone)
        return
    import_string(path)(drone=drone, title=title, detail=detail, source=source)
