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
- when no layer is clear, the plan is refused as a conflict.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Mapping, Sequence
from datetime import UTC, datetime
from typing import Any

from django.conf import settings

from fleet import envelopes
from fleet.models import Drone
from onboard import envelope as env

from . import reservations
from .corridors import Leg, takeoff_altitude, with_takeoff_altitude
from .index import Airspace, Clash, Flight, Reserved

CONFLICT = "conflict"


class Conflict(envelopes.OutsideEnvelope):
    """A flight that would come within the separation minima of another drone's
    reservation; `clash` says whose, where and when."""

    code = CONFLICT

    def __init__(self, clash: Clash, own_organisation_id: int, minima: tuple[float, float]) -> None:
        super().__init__(env.Violation("separation", describe(clash, own_organisation_id, minima)))
        self.clash = clash


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


def check_legs(drone: Drone, legs: Sequence[Leg], others: Sequence[Reserved]) -> None:
    """Raise Conflict when the drone's legs come within the minima of `others`."""
    flight, minima = _flight(drone, legs)
    clash = Airspace(others).first_conflict(flight)
    if clash is not None:
        raise Conflict(clash, drone.organisation_id, minima)


def check_mission(drone: Drone, steps: Sequence[Mapping[str, Any]]) -> None:
    """Raise Conflict when the drone flying `steps` from where it is would come within
    the minima of another drone's reservation. Call inside the transaction that then
    creates the assignment: the airspace stays locked until it commits."""
    planned = reservations.planned_legs(drone, steps)
    if planned is None:
        return
    reservations.lock(drone.organisation_id)
    check_legs(drone, planned[0], reservations.others(drone.organisation, [drone.pk]))


def check_command(drone: Drone, command: str, params: Mapping[str, Any]) -> None:
    """Raise Conflict for a navigation command (not a land: coming down is never refused)
    whose leg or hover after it comes within the minima of another drone's reservation."""
    if command not in reservations.MOVING_COMMANDS or command == "land":
        return
    planned = reservations.planned_legs(drone, [{"command": command, "params": dict(params)}])
    if planned is None:
        return
    check_legs(drone, planned[0], reservations.others(drone.organisation, [drone.pk]))


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


def layered_steps(
    drone: Drone, steps: Sequence[Mapping[str, Any]], others: Sequence[Reserved]
) -> tuple[list[dict], list[Leg]]:
    """The steps on the first clear layer (their takeoff's altitude, then higher by
    layer_step up to the drone's ceiling) and their legs; Conflict when none is clear."""
    base = takeoff_altitude(steps)
    ceiling = envelopes.drone_envelope(drone).max_height
    altitudes = [base] if base is not None else [None]
    step = layer_step(drone.organisation_id)
    while base is not None and altitudes[-1] + step <= ceiling:
        altitudes.append(altitudes[-1] + step)
    first: Conflict | None = None
    for altitude in altitudes:
        tried = list(steps) if altitude is None else with_takeoff_altitude(steps, altitude)
        planned = reservations.planned_legs(drone, tried)
        if planned is None:
            return [dict(s) for s in tried], []
        try:
            check_legs(drone, planned[0], others)
        except Conflict as exc:
            first = first or exc
            continue
        return [dict(s) for s in tried], planned[0]
    raise first  # type: ignore[misc]


def layered_handover(handover: Any, drones: Sequence[Drone]) -> Any:
    """A replacement's or a split's plan (missions/handover.py Handover) with each part's
    takeoff on a clear layer; Conflict when a part has none. The drones planned here are
    checked against everything but their own present reservations (their plans change)."""
    by_id = {d.drone_id: d for d in drones}
    if not drones:
        return handover
    reservations.lock(drones[0].organisation_id)
    placed = reservations.others(drones[0].organisation, [d.pk for d in drones])
    # Drones that keep their height (no takeoff) are laid first, then the others in order.
    order = sorted(handover.assignments, key=lambda p: takeoff_altitude(p.steps) is not None)
    laid = {}
    for part in order:
        drone = by_id[part.drone_id]
        steps, legs = layered_steps(drone, part.steps, placed)
        placed.append(_as_reserved(drone, legs))
        laid[id(part)] = steps
    parts = [dataclasses.replace(p, steps=laid[id(p)]) for p in handover.assignments]
    changed = {s["index"]: s for p in parts for s in p.steps if "index" in s}
    new_steps = [changed.get(s["index"], s) for s in handover.new_steps]
    return dataclasses.replace(handover, assignments=parts, new_steps=new_steps)
