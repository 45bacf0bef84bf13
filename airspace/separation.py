"""Separation between the platform's own drones: every flight is checked against the
airspace the others reserved (airspace/reservations.py) before it is sent.

A flight the operator asks for (a mission start, a panic call, a navigation command)
that would come within the minima of another drone's reservation is refused: 409
`conflict`, naming the other drone, the place and the time. Where the platform plans
the flight itself (a replacement, a collaboration's split of an area among drones) it
solves the conflict instead, with altitude layers:

- a drone that takes off climbs to the plan's altitude, else to the first layer above it
  that is clear: layers are `vertical minimum + 2 × vertical tolerance` apart, so that
  two drones on neighbouring layers have bands exactly the vertical minimum apart;
- no layer above the drone's envelope ceiling (its maximum height) is used; a drone
  already in the air keeps its height;
- the drones of one split are laid one by one, those already in the air (keeping their
  height) first, then the others in the split's order, each clear of the other drones'
  reservations and of the parts laid before it;
- when no layer is clear for a drone that takes off (a layer does not separate a takeoff
  or a landing from the drones flying under it), its departure is staggered: it waits on
  the ground, before it arms, on the lowest layer a wait clears, the shortest such wait;
- when neither solves it, the plan is refused as a conflict.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Mapping, Sequence
from datetime import UTC, datetime
from typing import Any

from django.conf import settings
from django.utils import timezone

from fleet import envelopes
from fleet.models import Drone
from onboard import envelope as env

from . import landing, reservations
from .corridors import SIDEWAYS, Leg, flight_legs, takeoff_altitude
from .index import Airspace, Clash, Flight, Reserved
from .stagger import Laid, Search, departure, lay

CONFLICT = "conflict"


class Conflict(envelopes.OutsideEnvelope):
    """A flight that would come within the separation minima of another drone's
    reservation; `clash` says whose, where and when."""

    code = CONFLICT

    def __init__(
        self,
        clash: Clash,
        own_organisation_id: int,
        minima: tuple[float, float],
        step: int | None = None,
    ) -> None:
        violation = env.Violation("separation", describe(clash, own_organisation_id, minima))
        super().__init__(violation, step)
        self.clash = clash


def step_of(legs: Sequence[Leg], clash: Clash, steps: Sequence[Mapping[str, Any]]) -> int | None:
    """The step whose leg (or piece of a slanted leg) met the reservation: its mission
    index, else its position among `steps`; None for the hover after the last step."""
    position = legs[clash.leg].step
    if position is None or not 0 <= position < len(steps):
        return None
    index = steps[position].get("index", position)
    return index if isinstance(index, int) and not isinstance(index, bool) else position


def step_extent(legs: Sequence[Leg], k: int) -> tuple[Leg, Leg]:
    """The first and last of the legs flying the same step as legs[k] (the pieces of a
    slanted leg lie one after the other)."""
    first = last = k
    while first > 0 and legs[first - 1].step == legs[k].step:
        first -= 1
    while last + 1 < len(legs) and legs[last + 1].step == legs[k].step:
        last += 1
    return legs[first], legs[last]


def describe(clash: Clash, own_organisation_id: int, minima: tuple[float, float]) -> str:
    """The refusal's sentence; a drone of another organisation is not named."""
    other = clash.reserved
    whose = (
        f"drone {other.drone_id}"
        if other.organisation_id == own_organisation_id
        else "a drone of another organisation"
    )
    # Windows open early (their buffer): a conflict whose overlap has begun is from now.
    at = datetime.fromtimestamp(max(clash.at, time.time()), tz=UTC).isoformat(timespec="seconds")
    horizontal = max(minima[0], other.horizontal_min_m)
    vertical = max(minima[1], other.vertical_min_m)
    return (
        f"The flight comes within the separation minima ({horizontal:g} m horizontally, "
        f"{vertical:g} m vertically) of {whose}'s reserved airspace at "
        f"{clash.lat:.6f}, {clash.lon:.6f} from {at}."
    )


def _flight(drone: Drone, legs: Sequence[Leg]) -> tuple[Flight, tuple[float, float]]:
    minima = reservations.minima_for(drone.organisation_id)
    return Flight(legs, settings.AIRSPACE_CORRIDOR_RADIUS_M, *minima), minima


def check_legs(
    drone: Drone,
    legs: Sequence[Leg],
    others: Sequence[Reserved],
    steps: Sequence[Mapping[str, Any]] | None = None,
) -> None:
    """Raise Conflict when the drone's legs come within the minima of `others`, naming
    the step of `steps` (a mission's) that meets them."""
    flight, minima = _flight(drone, legs)
    clash = Airspace(others).first_conflict(flight)
    if clash is not None:
        step = step_of(legs, clash, steps) if steps is not None else None
        raise Conflict(clash, drone.organisation_id, minima, step)


def check_mission(drone: Drone, steps: Sequence[Mapping[str, Any]]) -> None:
    """Raise Conflict when the drone flying `steps` from where it is would come within
    the minima of another drone's reservation. Call inside the transaction that then
    creates the assignment: the airspace stays locked until it commits."""
    planned = reservations.planned_legs(drone, steps)
    if planned is None:
        return
    reservations.lock(drone.organisation_id)
    check_legs(drone, planned[0], reservations.others(drone.organisation, [drone.pk]), steps)


def plan_conflicts(drone: Drone, steps: Sequence[Mapping[str, Any]]) -> list[dict]:
    """For the planner: where the drone flying `steps` from where it is now would first
    come within the minima of another drone's reservation (nothing is locked or kept)."""
    planned = reservations.planned_legs(drone, steps)
    if planned is None:
        return []
    legs = planned[0]
    flight, minima = _flight(drone, legs)
    clash = Airspace(reservations.others(drone.organisation, [drone.pk])).first_conflict(flight)
    if clash is None:
        return []
    leg = legs[clash.leg]
    first, last = step_extent(legs, clash.leg)
    own = clash.reserved.organisation_id == drone.organisation_id
    return [
        {
            "message": describe(clash, drone.organisation_id, minima),
            "drone": clash.reserved.drone_id if own else None,
            "step": step_of(legs, clash, steps),
            "at": [clash.lat, clash.lon],
            "leg": [[first.lat0, first.lon0], [last.lat1, last.lon1]],
            "band_m": [leg.low, leg.high],
        }
    ]


def check_command(drone: Drone, command: str, params: Mapping[str, Any]) -> None:
    """Raise Conflict for a navigation command (not a land: coming down is never refused)
    whose leg or hover after it comes within the minima of another drone's reservation."""
    if command not in reservations.MOVING_COMMANDS or command == "land":
        return
    if landing.is_queue_hold(drone, command, params):
        return  # the landing queue's layers separate it (airspace/landing.py)
    steps = [{"command": command, "params": dict(params)}]
    if command in SIDEWAYS:
        steps = [*climb_under_way(drone), *steps]
    planned = reservations.planned_legs(drone, steps)
    if planned is None:
        return
    check_legs(drone, planned[0], reservations.others(drone.organisation, [drone.pk]))


def climb_under_way(drone: Drone) -> list[dict]:
    """A drone in the air still climbing (or descending) to the height of the last target
    it accepted, more than the vertical tolerance away: that climb as an `altitude` step.
    A sideways command sent now is flown from its height on a slant to the target at that
    height (onboard/navigation.py adds it to the last target), and is checked so."""
    rise = envelopes.rise_under_way(drone)
    return [] if rise is None else [{"command": "altitude", "params": {"value": rise}}]


def reserve_command(drone: Drone, command: str, reply: Mapping[str, Any] | None) -> None:
    """After the drone accepted a navigation command (fleet/envelopes.py remember_target):
    the leg to the target its reply names, and the hover there, become its reservation."""
    if not envelopes.moves_target(command, reply):
        return
    target = reply["result"]["target"]  # type: ignore[index]
    home = envelopes.home_of(drone)
    here = reservations.position_of(drone)
    if home is None or here is None or target.get("north") is None:
        return
    lat, lon = env.ned_to_latlon(float(target["north"]), float(target["east"]), home)
    if landing.is_queue_hold(drone, command, {"lat": lat, "lon": lon}):
        return  # its reservation is the queue's: the hold, then its way down
    height = -float(target.get("down") or 0.0)
    params = {"lat": lat, "lon": lon, "altitude_delta": height - here[2]}
    reservations.reserve_command(drone, "navigate", params)


def reserve_way_down(drone: Drone, then: str) -> None:
    """A drone told to stop and come down ("land" where it is, "return" home at its
    height then land) reserves that way down, in place of its plan's corridors."""
    steps: list[dict] = [{"command": "land"}]
    home = envelopes.home_of(drone)
    if then == "return" and home is not None:
        steps.insert(0, {"command": "navigate", "params": {"lat": home[0], "lon": home[1]}})
    reservations.reserve_steps(drone, steps, then)


# -- layers -------------------------------------------------------------------------------


def layer_step(organisation_id: int) -> float:
    """Layers' spacing: bands of neighbouring layers are the vertical minimum apart."""
    vertical = reservations.minima_for(organisation_id)[1]
    return vertical + 2 * settings.AIRSPACE_VERTICAL_TOLERANCE_M


def _as_reserved(drone: Drone, legs: Sequence[Leg]) -> Reserved:
    flight, _ = _flight(drone, legs)
    return Reserved(
        f"plan:{drone.drone_id}", drone.drone_id, drone.organisation_id,
        [leg.to_list() for leg in legs],
        flight.radius_m, flight.horizontal_min_m, flight.vertical_min_m,
    )  # fmt: skip


def _layers(drone: Drone, base: float | None) -> list[float | None]:
    """The plan's takeoff altitude, then higher by layer_step up to the drone's ceiling."""
    if base is None:
        return [None]
    ceiling = envelopes.drone_envelope(drone).max_height
    step = layer_step(drone.organisation_id)
    altitudes: list[float | None] = [base]
    while altitudes[-1] + step <= ceiling:  # type: ignore[operator]
        altitudes.append(altitudes[-1] + step)  # type: ignore[operator]
    return altitudes


def layered_steps(
    drone: Drone, steps: Sequence[Mapping[str, Any]], others: Sequence[Reserved]
) -> Laid:
    """The steps on the first clear layer (their takeoff's altitude, then higher by
    layer_step up to the drone's ceiling). When no layer is clear for a drone that takes
    off, its departure is staggered: on the lowest layer a wait on the ground clears, the
    shortest such wait (a multiple of AIRSPACE_STAGGER_STEP_S, at most
    AIRSPACE_STAGGER_MAX_S; airspace/stagger.py). Conflict (the first met at once) when
    neither solves it; a drone already in the air keeps its height and leaves at once."""
    position = reservations.position_of(drone)
    if position is None:
        return Laid([dict(s) for s in steps], [])
    minima = reservations.minima_for(drone.organisation_id)
    search = Search(
        position, timezone.now().timestamp(), reservations.pace_for(drone), minima,
        settings.AIRSPACE_STAGGER_STEP_S, settings.AIRSPACE_STAGGER_MAX_S,
    )  # fmt: skip
    layers = _layers(drone, takeoff_altitude(steps))
    laid, clash = lay(steps, layers, Airspace(others), search)
    if laid is None:
        # The clash met at once on the first layer: the plan's own takeoff altitude.
        legs, _ = flight_legs(steps, search.position, search.began, search.pace)
        step = step_of(legs, clash, steps)  # type: ignore[arg-type]
        raise Conflict(clash, drone.organisation_id, minima, step)  # type: ignore[arg-type]
    return laid


def layered_handover(handover: Any, drones: Sequence[Drone]) -> Any:
    """A replacement's or a split's plan (missions/handover.py Handover) with each part's
    takeoff on a clear layer, its departure staggered when no layer is clear at once;
    Conflict when a part has neither. The drones planned here are checked against
    everything but their own present reservations (their plans change), and each against
    the parts laid before it."""
    by_id = {d.drone_id: d for d in drones}
    if not drones:
        return handover
    reservations.lock(drones[0].organisation_id)
    placed = reservations.others(drones[0].organisation, [d.pk for d in drones])
    # Drones that keep their height (no takeoff) are laid first, then the others in order.
    order = sorted(handover.assignments, key=lambda p: takeoff_altitude(p.steps) is not None)
    laid: dict[int, Laid] = {}
    for part in order:
        drone = by_id[part.drone_id]
        laid[id(part)] = layered_steps(drone, part.steps, placed)
        placed.append(_as_reserved(drone, laid[id(part)].legs))
    parts = [dataclasses.replace(p, steps=laid[id(p)].steps) for p in handover.assignments]
    changed = {s["index"]: s for p in parts for s in p.steps if "index" in s}
    new_steps = [changed.get(s["index"], s) for s in handover.new_steps]
    layered = dataclasses.replace(handover, assignments=parts, new_steps=new_steps)
    delays = [laid[id(p)].delay_s for p in handover.assignments]
    return _with_departures(layered, delays) if any(delays) else layered


def _with_departures(handover: Any, delays: Sequence[float]) -> Any:
    """Each delayed part starts with its wait on the ground, a new preparation step. New
    steps are numbered again in flying order, part by part, from the first new index (the
    mission's highest plus one): an index is never reused or skipped."""
    new = {s["index"] for s in handover.new_steps}
    every = [s["index"] for p in handover.assignments for s in p.steps]
    next_index = min(new) if new else max([*every, *handover.superseded_indexes, -1]) + 1
    parts, new_steps = [], []
    for part, delay in zip(handover.assignments, delays, strict=True):
        wait = [{"index": None, **departure(delay)}] if delay else []
        numbers: dict[int | None, int] = {}
        steps = []
        for step in [*wait, *part.steps]:
            if step["index"] is None or step["index"] in new:
                numbers[step["index"]] = next_index
                step = {**step, "index": next_index}
                next_index += 1
                new_steps.append(step)
            steps.append(step)
        preparation = [numbers[None]] if delay else []
        preparation += [numbers.get(i, i) for i in part.preparation_indexes]
        parts.append(dataclasses.replace(part, steps=steps, preparation_indexes=preparation))
    return dataclasses.replace(handover, assignments=parts, new_steps=new_steps)
