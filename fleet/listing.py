"""The fleet table and map of an organisation of any size: search, filters, pages, and
the map's marker columns, read with `values()` (no model instances: 10 000 drones in one
snapshot must stay cheap)."""

from __future__ import annotations

from dataclasses import dataclass

from django.conf import settings
from django.db.models import Q, QuerySet
from django.utils.module_loading import import_string

from . import airworthiness
from .models import Drone
from .state import LOW_BATTERY_FRACTION, STATES, describe, drone_state

# Filters the table offers; each narrows the search (they combine with AND).
FILTERS: dict[str, Q] = {
    "online": Q(online=True),
    "airborne": Q(online=True, airborne=True),
    "mission": Q(mission__isnull=False),
    "low_battery": Q(online=True, battery_remaining__lte=LOW_BATTERY_FRACTION),
    "lost_link": Q(online=False),
}
PAGE_SIZE = 50
MAX_PAGE_SIZE = 500
_FIELDS = (
    "drone_id",
    "name",
    "online",
    "last_seen",
    "lat",
    "lon",
    "alt",
    "battery_voltage",
    "battery_remaining",
    "armed",
    "airborne",
    "flight_mode",
    "mission",
    "fc",
    "home",
)


class BadQuery(ValueError):
    """A filter or page the table does not know."""


@dataclass(frozen=True)
class TableQuery:
    search: str = ""
    filters: tuple[str, ...] = ()
    page: int = 1
    page_size: int = PAGE_SIZE

    @classmethod
    def from_params(cls, params) -> TableQuery:  # type: ignore[no-untyped-def]
        """From a request's GET: q, filter (repeated or comma-separated), page, page_size."""
        names = [n for value in params.getlist("filter") for n in value.split(",") if n]
        unknown = sorted(set(names) - FILTERS.keys())
        if unknown:
            raise BadQuery(f"unknown filter {', '.join(unknown)}; known: {', '.join(FILTERS)}")
        try:
            page = int(params.get("page", 1))
            size = int(params.get("page_size", PAGE_SIZE))
        except ValueError as exc:
            raise BadQuery("page and page_size are whole numbers") from exc
        if page < 1 or not 1 <= size <= MAX_PAGE_SIZE:
            raise BadQuery(f"page starts at 1; page_size is 1 to {MAX_PAGE_SIZE}")
        return cls(params.get("q", "").strip()[:100], tuple(dict.fromkeys(names)), page, size)


def matching(drones: QuerySet, query: TableQuery) -> QuerySet:
    if query.search:
        drones = drones.filter(
            Q(drone_id__icontains=query.search) | Q(name__icontains=query.search)
        )
    for name in query.filters:
        drones = drones.filter(FILTERS[name])
    return drones


def row(values: dict) -> dict:
    """One drone in the drone API's shape, with its state."""
    lat, lon = values["lat"], values["lon"]
    voltage, remaining = values["battery_voltage"], values["battery_remaining"]
    last_seen = values["last_seen"]
    return describe(
        {
            "drone_id": values["drone_id"],
            "name": values["name"],
            "online": values["online"],
            "last_seen": last_seen.isoformat() if last_seen else None,
            "position": None
            if lat is None or lon is None
            else {"lat": lat, "lon": lon, "alt": values["alt"]},
            "battery": None
            if voltage is None and remaining is None
            else {"voltage": voltage, "remaining": remaining},
            "armed": values["armed"],
            "airborne": values["airborne"],
            "flight_mode": values["flight_mode"],
            "mission": values["mission"],
            "fc": values["fc"],
            "home": values["home"],
        }
    )


def table_page(organisation_id: int, query: TableQuery) -> dict:
    """One page of the organisation's drones matching `query`, and how many match."""
    drones = matching(Drone.objects.filter(organisation_id=organisation_id), query)
    count = drones.count()
    start = (query.page - 1) * query.page_size
    # A page past the last is empty, asked of nobody (an offset past bigint would fail).
    rows = drones.order_by("drone_id").values(*_FIELDS)[start : start + query.page_size]
    results = [row(values) for values in rows] if start < count else []
    ready = readiness(organisation_id, [r["drone_id"] for r in results])
    return {
        "count": count,
        "page": query.page,
        "page_size": query.page_size,
        "pages": max(1, -(-count // query.page_size)),
        "results": [{**r, "readiness": ready[r["drone_id"]]} for r in results],
    }


def readiness(organisation_id: int, drone_ids: list[str]) -> dict[str, dict]:
    """Per drone of one table page: whether it is airworthy and why not
    (fleet/airworthiness.py), and its pre-flight checklist state (the checklists app,
    named in settings as it builds on this one)."""
    drones = list(
        Drone.objects.filter(
            organisation_id=organisation_id, drone_id__in=drone_ids
        ).select_related("organisation")
    )
    checklists = import_string(settings.FLEET_CHECKLIST_STATES)(drones)
    verdicts = airworthiness.verdicts(drones)
    return {d.drone_id: {**verdicts[d.pk].to_dict(), "checklist": checklists[d.pk]} for d in drones}


# The map's columns: what it needs of every drone.
MARKER_FIELDS = ("drone_id", "lat", "lon", "alt", "state")


def marker_columns(organisation_id: int) -> dict:
    """Every placed drone of the organisation for the map's first draw, column by column
    (a list per field, `state` as an index into `states`): a third fewer bytes than a
    row per drone, and a page turns each column into one array without per-drone
    objects."""
    drones = Drone.objects.filter(
        organisation_id=organisation_id, lat__isnull=False, lon__isnull=False
    )
    fields = ("drone_id", "lat", "lon", "alt", "online", "armed", "airborne", "flight_mode")
    code = {state: i for i, state in enumerate(STATES)}
    ids: list[str] = []
    lats: list[float] = []
    lons: list[float] = []
    alts: list[float | None] = []
    states: list[int] = []
    # Unordered: the map needs no order, and sorting 10 000 ids costs more than the rest.
    rows = drones.order_by().values_list(*fields, "battery_remaining")
    for drone_id, lat, lon, alt, online, armed, airborne, mode, remaining in rows:
        ids.append(drone_id)
        lats.append(round(lat, 7))  # about a centimetre: a third of the bytes of a full float
        lons.append(round(lon, 7))
        alts.append(None if alt is None else round(alt, 1))
        state = drone_state(
            online=online,
            armed=armed,
            airborne=airborne,
            flight_mode=mode,
            battery_remaining=remaining,
        )
        states.append(code[state])
    columns = dict(zip(MARKER_FIELDS, (ids, lats, lons, alts, states), strict=True))
    return {"count": len(ids), "states": list(STATES), "columns": columns}
