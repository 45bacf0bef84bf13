"""Laying one of the platform's own flights clear of the others (no Django): on the first
clear altitude layer at once, else on the lowest layer a wait on the ground clears, after
the shortest such wait (airspace/separation.py gives it the drone, its layers and the
airspace; docs/airspace.md "Solved: altitude layers, staggered departures").

A wait on the ground before the drone arms is its own timer: it moves every leg's window
by all of it (airspace/corridors.py). So while a leg's window opens before a reserved
leg's closes, a pair that conflicts keeps conflicting however much longer the wait, up to
that point: the search jumps there, never past a clear wait, and tries few waits even in
a crowded airspace.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from .corridors import Leg, Pace, flight_legs, with_takeoff_altitude
from .index import Airspace, Clash, Flight


@dataclass(frozen=True)
class Laid:
    """A flight as the platform sends it: its steps on their layer, its legs, and how
    long its drone waits on the ground before it arms (0: it leaves at once)."""

    steps: list[dict]
    legs: list[Leg]
    delay_s: float = 0.0


@dataclass(frozen=True)
class Search:
    """Where the flight starts and how it is flown, what it must keep clear of."""

    position: tuple[float, float, float]
    began: float
    pace: Pace
    minima: tuple[float, float]
    step_s: float  # waits are multiples of this
    most_s: float  # and at most this long


def departure(delay_s: float) -> dict:
    """A staggered departure: the drone waits this long on the ground before it arms."""
    return {"command": "sleep", "params": {"value": float(delay_s)}}


def _attempt(
    steps: Sequence[Mapping[str, Any]],
    altitude: float | None,
    delay: float,
    search: Search,
    airspace: Airspace,
) -> tuple[Laid, Clash | None]:
    tried = list(steps) if altitude is None else with_takeoff_altitude(steps, altitude)
    flown = [departure(delay), *tried] if delay else tried
    legs, _ = flight_legs(flown, search.position, search.began, search.pace)
    flight = Flight(legs, search.pace.radius_m, *search.minima)
    return Laid([dict(s) for s in tried], legs, delay), airspace.first_conflict(flight)


def next_delay(laid: Laid, clash: Clash, search: Search) -> float | None:
    """The shortest wait that may clear the clash (the first multiple of the step at
    which the leg's window opens after the reserved leg's closes), None beyond the
    longest wait."""
    if search.step_s <= 0:
        return None
    needed = laid.delay_s + max(clash.until - laid.legs[clash.leg].t0, search.step_s)
    delay = math.ceil(needed / search.step_s - 1e-9) * search.step_s
    return delay if delay <= search.most_s else None


def lay(
    steps: Sequence[Mapping[str, Any]],
    layers: Sequence[float | None],
    reserved: Airspace,
    search: Search,
) -> tuple[Laid | None, Clash | None]:
    """(laid, None) on the first clear layer at once, else on the lowest layer a wait
    clears after the shortest such wait; (None, the first clash at once) when neither.
    `layers` is [None] for a flight that does not take off: it cannot wait."""
    legs, _ = flight_legs(steps, search.position, search.began, search.pace)
    # Layers and waits change heights and times, never the ground track: the reserved
    # legs near it are picked once.
    airspace = reserved.around(Flight(legs, search.pace.radius_m, *search.minima))
    at_once = []
    for altitude in layers:
        laid, clash = _attempt(steps, altitude, 0.0, search, airspace)
        if clash is None:
            return laid, None
        at_once.append((altitude, laid, clash))
    for altitude, laid, clash in at_once if layers[0] is not None else []:
        while clash is not None:
            delay = next_delay(laid, clash, search)
            if delay is None:
                break
            laid, clash = _attempt(steps, altitude, delay, search, airspace)
        if clash is None:
            return laid, None
    return None, at_once[0][2]


def lay_plainly(
    steps: Sequence[Mapping[str, Any]],
    layers: Sequence[float | None],
    reserved: Airspace,
    search: Search,
) -> tuple[Laid | None, Clash | None]:
    """The same answer as `lay`, every layer at once and then every multiple of the step
    on every layer in turn, each against the whole airspace: the definition `lay` is
    measured and tested against."""
    at_once = []
    for altitude in layers:
        laid, clash = _attempt(steps, altitude, 0.0, search, reserved)
        if clash is None:
            return laid, None
        at_once.append(clash)
    count = int(search.most_s // search.step_s) if search.step_s > 0 else 0
    for altitude in layers if layers[0] is not None else []:
        for k in range(1, count + 1):
            laid, clash = _attempt(steps, altitude, k * search.step_s, search, reserved)
            if clash is None:
                return laid, None
    return None, at_once[0]
