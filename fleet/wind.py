"""The ground's side of the wind rule (onboard/wind.py, docs/airspace.md "Wind").

A drone's limit is its gear's `MAX_WIND_M_S` (the specs it announced), else the default;
the wind is what its flight controller estimated, in the drone's last heartbeat
(`fc.wind`). The ground refuses a take-off (the `arm` and `takeoff` commands, a mission's
start on the drone) while that wind is above the limit, with 409 `wind` and the figure;
the drone refuses it too, and returns by itself when the wind stays above its limit in
flight (the heartbeat's `wind.action`, which raises a WARNING alert: alerts/wind.py).
"""

from __future__ import annotations

from onboard import wind as rule

from .models import Drone

# The API's error code of a refusal for wind.
CODE = "wind"
# Commands that start a flight; refused on the ground in a wind above the limit.
TAKE_OFF_COMMANDS = ("arm", "takeoff")


def limit_of(drone: Drone) -> float:
    """The drone's limit, m/s: its gear's, else the default (a malformed figure, which the
    drone itself refuses to adopt, counts as none)."""
    try:
        return rule.limit_from_specs(drone.specs)
    except rule.WindLimitError:
        return rule.DEFAULT_MAX_WIND_M_S


def reported(drone: Drone) -> dict | None:
    """The wind the drone's last heartbeat reported (None: its flight controller gives no
    estimate, or none yet)."""
    wind = (drone.fc or {}).get("wind")
    return wind if isinstance(wind, dict) and "speed" in wind else None


def effective_limit(drone: Drone) -> float:
    """The lower of the ground's figure and the one the drone says it enforces."""
    limit = limit_of(drone)
    wind = reported(drone)
    theirs = None if wind is None else wind.get("limit")
    return min(limit, float(theirs)) if isinstance(theirs, int | float) else limit


def refusal(drone: Drone) -> str | None:
    """Why the drone may not take off in its wind now, or None (no estimate, or within)."""
    wind = reported(drone)
    if wind is None or drone.airborne:
        return None
    found = rule.refusal(float(wind["speed"]), effective_limit(drone))
    return None if found is None else f"Drone {drone.drone_id}: {found}"


def above_limit(drone: Drone) -> str | None:
    """fleet/airworthiness.py's reason: a drone on the ground in a wind above its limit is
    not chosen for a flight (replacement, collaboration, panic)."""
    wind = reported(drone)
    if wind is None or drone.airborne:
        return None
    limit = effective_limit(drone)
    speed = float(wind["speed"])
    return None if speed <= limit else f"wind {speed:.1f} m/s above its limit of {limit:g} m/s"


def view(drone: Drone) -> dict | None:
    """What the drone page shows: the wind, where it comes from, the limit, whether above
    it and what the drone did."""
    wind = reported(drone)
    limit = effective_limit(drone)
    if wind is None:
        return {"known": False, "limit": limit}
    estimate = rule.Wind(
        float(wind.get("north", 0.0)),
        float(wind.get("east", 0.0)),
        float(wind.get("down", 0.0)),
        str(wind.get("source") or ""),
    )
    return {
        "known": True,
        "speed": float(wind["speed"]),
        "from_deg": round(estimate.from_deg),
        "down": estimate.down,
        "source": estimate.source,
        "limit": limit,
        "above": float(wind["speed"]) > limit,
        "action": wind.get("action"),
    }
