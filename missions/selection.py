"""Which drones may join or replace a mission: the rule on plain values (`select_drones`),
and the one read of an organisation's drones it is applied to (`nearest_available`).

A drone is available when it is online, not flying another mission, airworthy
(fleet/airworthiness.py: Remote ID, ...), passes its organisation's automatic checklist
items where checklists are required (checklists/gate.py) and its battery is above the
reserve. Available drones are taken nearest first to where they are needed,
and between equally distant ones the fuller battery first.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

from django.conf import settings

from checklists import gate as checklists
from fleet import airworthiness, wind
from fleet.models import Drone
from missions.errors import MissionError
from missions.geo import distance_m
from missions.models import Assignment, Mission, MissionStatus

DEFAULT_BATTERY_RESERVE = 0.3
# Two drones this close to each other count as equally far; battery then decides.
DISTANCE_RESOLUTION_M = 1.0


@dataclass(frozen=True)
class Candidate:
    drone_id: str
    online: bool
    in_mission: bool
    battery: float | None  # remaining, 0..1; None when the drone has not reported it
    position: tuple[float, float] | None  # (lat, lon); None before the first GPS fix
    # fleet/airworthiness.py: no reason keeps it on the ground (Remote ID, ...).
    airworthy: bool = True
    # checklists/gate.py: it passes the organisation's automatic checklist items.
    checks_pass: bool = True


def is_available(candidate: Candidate, *, reserve: float = DEFAULT_BATTERY_RESERVE) -> bool:
    """Online, free, airworthy and above the reserve; a drone that never reported a battery
    is not."""
    return (
        candidate.online
        and candidate.airworthy
        and candidate.checks_pass
        and not candidate.in_mission
        and candidate.battery is not None
        and math.isfinite(candidate.battery)
        and candidate.battery > reserve
        and candidate.position is not None
    )


def select_drones(
    candidates: Sequence[Candidate],
    *,
    target: tuple[float, float],
    count: int,
    reserve: float = DEFAULT_BATTERY_RESERVE,
    exclude: Sequence[str] = (),
) -> list[Candidate]:
    """Up to `count` available drones, nearest to `target` first, then fuller battery first.

    `exclude` names drones that must not be chosen (e.g. the one being replaced). Fewer
    than `count` come back when fewer are available; the caller decides what that means.
    """
    if count < 0:
        raise ValueError("count must not be negative")
    excluded = set(exclude)
    usable = [
        c for c in candidates if c.drone_id not in excluded and is_available(c, reserve=reserve)
    ]
    if not usable or count == 0:
        return []
    lats = [c.position[0] for c in usable]  # type: ignore[index]
    lons = [c.position[1] for c in usable]  # type: ignore[index]
    distances = distance_m(lats, lons, target[0], target[1])
    ranked = sorted(
        zip(usable, distances.tolist(), strict=True),
        key=lambda pair: (
            round(pair[1] / DISTANCE_RESOLUTION_M),
            -(pair[0].battery or 0.0),
            pair[0].drone_id,
        ),
    )
    return [candidate for candidate, _ in ranked[:count]]


def busy_drone_ids(organisation_id: int) -> set[str]:
    """Drones holding an unfinished assignment of a running or paused mission."""
    return set(
        Assignment.objects.filter(
            drone__organisation_id=organisation_id,
            status__in=Assignment.ACTIVE,
            mission__status__in=(MissionStatus.RUNNING, MissionStatus.PAUSED),
        ).values_list("drone__drone_id", flat=True)
    )


def candidates(organisation_id: int) -> list[Candidate]:
    busy = busy_drone_ids(organisation_id)
    out = []
    drones = list(
        Drone.objects.filter(
            organisation_id=organisation_id, credentials_revoked=False
        ).select_related("organisation")
    )
    automatic = checklists.automatic_items_for(organisation_id) if drones else []
    # Every candidate judged at once (a fixed number of queries however many drones).
    verdicts = airworthiness.verdicts(drones)
    # What the drones' automatic items share: their envelope, and the verdicts.
    shared: dict = {"verdicts": verdicts}
    for drone in drones:
        position = None if drone.lat is None or drone.lon is None else (drone.lat, drone.lon)
        out.append(
            Candidate(
                drone_id=drone.drone_id,
                online=drone.online,
                in_mission=drone.drone_id in busy,
                battery=drone.battery_remaining,
                position=position,
                airworthy=verdicts[drone.pk].airworthy,
                checks_pass=not checklists.failing(drone, automatic, shared),
            )
        )
    return out


def nearest_available(
    organisation_id: int,
    *,
    target: tuple[float, float] | None,
    count: int = 1,
    exclude: Sequence[str] = (),
) -> list[Drone]:
    """Up to `count` available drones of the organisation, nearest to `target` first."""
    pool = candidates(organisation_id)
    if target is None:
        # Nothing to fly to: any place among the drones will do; battery then decides.
        placed = [c.position for c in pool if c.position is not None]
        if not placed:
            return []
        target = placed[0]
    chosen = select_drones(
        pool,
        target=target,
        count=count,
        reserve=settings.MISSIONS_BATTERY_RESERVE,
        exclude=exclude,
    )
    by_id = {d.drone_id: d for d in Drone.objects.filter(drone_id__in=[c.drone_id for c in chosen])}
    return [by_id[c.drone_id] for c in chosen]


def first_target(steps: Iterable[Mapping]) -> tuple[float, float] | None:
    for step in steps:
        if step["command"] == "navigate":
            return float(step["params"]["lat"]), float(step["params"]["lon"])
    return None


def check_chosen(mission: Mission, drone: Drone) -> None:
    if drone.organisation_id != mission.organisation_id:
        raise MissionError("drone", f"no drone {drone.drone_id!r} in this organisation", 404)
    pool = {c.drone_id: c for c in candidates(mission.organisation_id)}
    candidate = pool[drone.drone_id]
    if not candidate.online:
        raise MissionError("drone", f"drone {drone.drone_id} is offline", 409)
    if candidate.in_mission:
        raise MissionError("drone", f"drone {drone.drone_id} is flying another mission", 409)
    too_windy = wind.refusal(drone)
    if too_windy is not None:
        raise MissionError("drone", too_windy, 409, wind.CODE)
    unfit = airworthiness.refused(drone)
    if unfit is not None:
        raise MissionError("drone", unfit[0], 409, "not_airworthy", reasons=unfit[1])
    reserve = settings.MISSIONS_BATTERY_RESERVE
    if candidate.battery is None or candidate.battery <= reserve:
        raise MissionError(
            "drone", f"drone {drone.drone_id} has not reported a battery above {reserve:.0%}", 409
        )
