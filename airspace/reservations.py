"""Reservations in the database: made when a flight is sent, ended when the drone lands or
its plan changes, and read back as the airspace a new flight is checked against.

- A mission's assignment reserves its legs as it is created (sent, or queued behind the
  drone's previous one), flown from where the drone is now.
- A navigation command the drone accepted reserves its leg and the hover after it.
- A drone's new reservation ends its previous one: a drone flies one plan at a time.
- A reservation ends when its assignment is over (stopped, completed, rejected, failed),
  when the drone is seen on the ground (the heartbeat's `airborne`) after it was seen in
  the air or after `airborne_by` (it landed), or when its last window has passed.
- A drone seen in the air with no active reservation (a stopped mission hovering, a
  window run out) holds the column under it (airspace/corridors.py `hold_legs`).

`sweep` ends what is over; it runs before every check and listing, so no timer is needed.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from datetime import UTC, datetime
from typing import Any

from django.apps import apps
from django.conf import settings
from django.db import connection
from django.db.models import Exists, OuterRef, Q
from django.utils import timezone

from fleet.models import Drone, Organisation

from .corridors import Leg, Pace, flight_legs, hold_legs
from .index import Reserved
from .models import LandingSlot, Reservation, SeparationMinima

# Commands whose accepted target moves the drone (onboard/protocol.py NAVIGATION_COMMANDS).
MOVING_COMMANDS = ("takeoff", "land", "changeN", "changeE", "altitude", "navigate")
# The command the landing queue's own reservations are made under (airspace/landing.py).
LANDING_QUEUE = "landing queue"
_LOCK_SITE = 0x41495253  # the advisory lock's key when the whole site is one airspace


def pace_for(drone: Drone) -> Pace:
    """The drone's cruise speed from its gear (`CRUISE_SPEED_M_S`), else the setting; a
    slanted leg's pieces step by its organisation's vertical minimum (at least twice the
    vertical tolerance, so a zero minimum still cuts the slant)."""
    speed = (drone.specs or {}).get("CRUISE_SPEED_M_S")
    if not isinstance(speed, int | float) or isinstance(speed, bool) or speed <= 0:
        speed = settings.AIRSPACE_CRUISE_SPEED_M_S
    return Pace(
        speed_m_s=float(speed),
        climb_m_s=settings.AIRSPACE_CLIMB_SPEED_M_S,
        slack=settings.AIRSPACE_TIME_SLACK,
        early=settings.AIRSPACE_TIME_EARLY,
        buffer_s=settings.AIRSPACE_TIME_BUFFER_S,
        hold_s=settings.AIRSPACE_HOLD_S,
        radius_m=settings.AIRSPACE_CORRIDOR_RADIUS_M,
        vertical_m=settings.AIRSPACE_VERTICAL_TOLERANCE_M,
        step_m=max(
            minima_for(drone.organisation_id)[1], 2 * settings.AIRSPACE_VERTICAL_TOLERANCE_M
        ),
    )


def minima_for(organisation_id: int) -> tuple[float, float]:
    """(horizontal, vertical) metres the organisation keeps: its own, else the settings."""
    row = SeparationMinima.objects.filter(organisation_id=organisation_id).first()
    if row is None:
        return settings.AIRSPACE_HORIZONTAL_MIN_M, settings.AIRSPACE_VERTICAL_MIN_M
    return row.horizontal_m, row.vertical_m


def position_of(drone: Drone) -> tuple[float, float, float] | None:
    if drone.lat is None or drone.lon is None:
        return None
    return drone.lat, drone.lon, drone.alt or 0.0


def lock(organisation_id: int) -> None:
    """Serialise checks and reservations of one airspace until the transaction ends, so
    two flights checked at once cannot both take the same corridor."""
    key = _LOCK_SITE if settings.AIRSPACE_SITE_WIDE else organisation_id
    with connection.cursor() as cursor:
        cursor.execute("SELECT pg_advisory_xact_lock(%s, %s)", [_LOCK_SITE, key])


def _stamp(t: float) -> datetime:
    return datetime.fromtimestamp(t, tz=UTC)


# -- ending -------------------------------------------------------------------------------


def _over_assignments() -> Q:
    active = apps.get_model("missions", "Assignment").ACTIVE
    return Q(assignment__isnull=False) & ~Q(assignment__status__in=list(active))


def sweep(now: datetime | None = None) -> int:
    """End every reservation that is over; how many."""
    now = now or timezone.now()
    live = Reservation.objects.filter(ended_at__isnull=True)
    live.filter(flown=False, drone__airborne=True).update(flown=True)
    ended = live.filter(_over_assignments()).update(ended_at=now, end_reason="plan ended")
    ended += live.filter(Q(flown=True) | Q(airborne_by__lt=now), drone__airborne=False).update(
        ended_at=now, end_reason="landed"
    )
    ended += live.filter(ends_at__lt=now).update(ended_at=now, end_reason="window passed")
    return ended


def end_for_drone(drone: Drone, reason: str) -> None:
    Reservation.objects.filter(drone=drone, ended_at__isnull=True).update(
        ended_at=timezone.now(), end_reason=reason[:80]
    )


# -- making -------------------------------------------------------------------------------


def reserve(
    drone: Drone,
    legs: Sequence[Leg],
    airborne_by: float,
    *,
    kind: str,
    assignment: Any = None,
    command: str = "",
) -> Reservation | None:
    """Store the drone's corridors, ending its previous reservation; a plan other than
    the landing queue's own takes the drone out of the queue."""
    end_for_drone(drone, "replaced by a new plan")
    if command != LANDING_QUEUE:
        LandingSlot.objects.filter(drone=drone, ended_at__isnull=True).update(
            ended_at=timezone.now(), end_reason="commanded otherwise"
        )
    if not legs:
        return None
    horizontal, vertical = minima_for(drone.organisation_id)
    lats = [v for leg in legs for v in (leg.lat0, leg.lat1)]
    lons = [v for leg in legs for v in (leg.lon0, leg.lon1)]
    return Reservation.objects.create(
        organisation_id=drone.organisation_id,
        drone=drone,
        kind=kind,
        assignment=assignment,
        command=command,
        legs=[leg.to_list() for leg in legs],
        starts_at=_stamp(min(leg.t0 for leg in legs)),
        ends_at=_stamp(max(leg.t1 for leg in legs)),
        airborne_by=_stamp(airborne_by),
        radius_m=settings.AIRSPACE_CORRIDOR_RADIUS_M,
        horizontal_min_m=horizontal,
        vertical_min_m=vertical,
        min_lat=min(lats),
        max_lat=max(lats),
        min_lon=min(lons),
        max_lon=max(lons),
    )


def planned_legs(drone: Drone, steps: Sequence[Mapping]) -> tuple[list[Leg], float] | None:
    """The drone's corridors flying `steps` from where it is now, or None when the ground
    does not know where it is."""
    position = position_of(drone)
    if position is None:
        return None
    return flight_legs(steps, position, timezone.now().timestamp(), pace_for(drone))


def _assignment_steps(assignment: Any) -> list[dict]:
    indexes = list(assignment.preparation) + list(assignment.step_indexes)
    rows = assignment.mission.steps.filter(index__in=indexes)
    by_index = {s.index: {"command": s.command, "params": s.params} for s in rows}
    return [by_index[i] for i in indexes if i in by_index]


def reserve_when_assigned(sender: Any, instance: Any, created: bool = False, **kwargs: Any) -> None:
    """post_save of a mission's assignment: a new one reserves its drone's corridors."""
    if not created or instance.status not in type(instance).ACTIVE:
        return
    reserve_assignment(instance)


def reserve_assignment(instance: Any) -> None:
    """The assignment's steps flown from where its drone is now become its reservation
    (also when its steps changed before it was sent: a queued part that must take off)."""
    drone = Drone.objects.get(pk=instance.drone_id)
    planned = planned_legs(drone, _assignment_steps(instance))
    if planned is None:
        return
    legs, airborne_by = planned
    reserve(drone, legs, airborne_by, kind=Reservation.Kind.MISSION, assignment=instance)


def reserve_command(drone: Drone, command: str, params: Mapping[str, Any]) -> None:
    """The drone accepted a navigation command: its leg and the hover after it (a land:
    the descent) replace its previous reservation."""
    if command in MOVING_COMMANDS:
        reserve_steps(drone, [{"command": command, "params": dict(params)}], command)


def reserve_steps(drone: Drone, steps: Sequence[Mapping], command: str) -> None:
    """Steps the ground sent the drone outside a mission replace its reservation."""
    planned = planned_legs(drone, steps)
    if planned is None:
        return
    legs, airborne_by = planned
    reserve(drone, legs, airborne_by, kind=Reservation.Kind.COMMAND, command=command)


# -- reading ------------------------------------------------------------------------------


def _scope(organisation: Organisation) -> Q:
    return Q() if settings.AIRSPACE_SITE_WIDE else Q(organisation=organisation)


def active(organisation: Organisation) -> Iterable[Reservation]:
    """The reservations in force in the organisation's airspace (every organisation's,
    when AIRSPACE_SITE_WIDE), after ending what is over."""
    sweep()
    return (
        Reservation.objects.filter(_scope(organisation), ended_at__isnull=True)
        .select_related("drone")
        .order_by("starts_at", "pk")
    )


def _reserved(row: Reservation) -> Reserved:
    return Reserved(
        key=str(row.pk),
        drone_id=row.drone.drone_id,
        organisation_id=row.organisation_id,
        legs=row.legs,
        radius_m=row.radius_m,
        horizontal_min_m=row.horizontal_min_m,
        vertical_min_m=row.vertical_min_m,
    )


def _holds(organisation: Organisation, exclude: Sequence[int]) -> list[Reserved]:
    """Drones in the air with no reservation: the column under each."""
    reserved = Reservation.objects.filter(drone=OuterRef("pk"), ended_at__isnull=True)
    drones = (
        Drone.objects.filter(_scope(organisation), airborne=True, lat__isnull=False)
        .exclude(pk__in=list(exclude))
        .exclude(Exists(reserved))
    )
    now = timezone.now().timestamp()
    out = []
    for drone in drones:
        pace = pace_for(drone)
        horizontal, vertical = minima_for(drone.organisation_id)
        legs = [leg.to_list() for leg in hold_legs(position_of(drone), now, pace)]  # type: ignore[arg-type]
        if legs:
            out.append(
                Reserved(
                    f"hold:{drone.drone_id}",
                    drone.drone_id,
                    drone.organisation_id,
                    legs,
                    pace.radius_m,
                    horizontal,
                    vertical,
                )  # fmt: skip
            )
    return out


def others(organisation: Organisation, exclude: Sequence[int]) -> list[Reserved]:
    """What a flight of `organisation` must keep clear of: every active reservation and
    every unreserved airborne drone of its airspace, but those of the drones `exclude`
    (primary keys: the drones being planned)."""
    rows = [r for r in active(organisation) if r.drone_id not in set(exclude)]
    return [_reserved(r) for r in rows] + _holds(organisation, exclude)
