"""The automatic items, measured from the drone's live state: its last heartbeat (the
Drone row), its newest GPS telemetry sample, its envelope, and the airworthiness verdict
(fleet/airworthiness.py), which is reused rather than judged again here.

Each measure returns a `Result`: the value seen, whether it passes the threshold and a
sentence saying why not. A value the ground has not received fails: a check that cannot
be made is not passed.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from datetime import datetime
from typing import Any

from django.conf import settings
from django.utils import timezone

from fleet import airworthiness, envelopes, wind
from fleet.models import Drone
from onboard import envelope as env
from telemetry import queries

from .items import CHECKS

GPS_OBJECT = "GPSPosition"
# GPSPosition.Status values (LibrePilot's UAVO, which the MAVLink driver maps to) of a 3D fix.
FIX_3D = ("Fix3D", "Fix3DDGPS", "FixRTK")
REMOTE_ID_REASONS = (
    airworthiness.remote_id_failing,
    airworthiness.no_serial_number,
    airworthiness.no_operator_registration,
    airworthiness.no_broadcast,
)


@dataclass(frozen=True)
class Result:
    check: str
    threshold: float | None
    value: Any
    passed: bool
    why: str = ""

    def to_dict(self) -> dict:
        return {
            "kind": "auto",
            "check": self.check,
            "label": CHECKS[self.check].label,
            "threshold": self.threshold,
            "value": self.value,
            "passed": self.passed,
            "why": self.why,
        }


def _gps(drone: Drone, threshold: float, cache: dict) -> Result:
    sample = queries.latest(drone.pk, [GPS_OBJECT]).get(GPS_OBJECT)
    if sample is None:
        return Result("gps", threshold, None, False, "no GPS telemetry received")
    fields = sample["fields"]
    age = round(time.time() - sample["ts"], 1)
    value = {"fix": fields.get("Status"), "satellites": fields.get("Satellites"), "age_s": age}
    if age > settings.CHECKLIST_LIVE_MAX_AGE_S:
        return Result("gps", threshold, value, False, f"GPS telemetry {age:g} s old")
    if value["fix"] not in FIX_3D:
        return Result("gps", threshold, value, False, f"no 3D fix ({value['fix']})")
    satellites = value["satellites"]
    if not isinstance(satellites, int | float) or satellites < threshold:
        return Result(
            "gps", threshold, value, False, f"{satellites} satellites, {threshold:g} needed"
        )
    return Result("gps", threshold, value, True)


def _battery(drone: Drone, threshold: float, cache: dict) -> Result:
    charge = drone.battery_remaining
    if charge is None:
        return Result("battery", threshold, None, False, "no battery level reported")
    if charge < threshold:
        return Result(
            "battery", threshold, charge, False, f"battery at {charge:.0%}, {threshold:.0%} needed"
        )
    return Result("battery", threshold, charge, True)


def _now(cache: dict) -> datetime:
    """One clock reading for a batch of drones."""
    if "now" not in cache:
        cache["now"] = timezone.now()
    return cache["now"]


def _link(drone: Drone, threshold: float, cache: dict) -> Result:
    if not drone.online or drone.last_seen is None:
        return Result("link", threshold, None, False, "drone offline")
    age = round((_now(cache) - drone.last_seen).total_seconds(), 1)
    linked = bool((drone.fc or {}).get("connected"))
    value = {"heartbeat_age_s": age, "fc_connected": linked}
    if not linked:
        return Result("link", threshold, value, False, "flight controller not connected")
    if age > threshold:
        return Result("link", threshold, value, False, f"last heartbeat {age:g} s ago")
    return Result("link", threshold, value, True)


def _organisation_envelope(drone: Drone, cache: dict) -> env.Envelope:
    """The organisation's envelope, parsed once per organisation for a batch of drones."""
    key = ("envelope", drone.organisation_id)
    if key not in cache:
        cache[key] = envelopes.organisation_envelope(drone.organisation)
    return cache[key]


def _envelope(drone: Drone, threshold: None, cache: dict) -> Result:
    home = envelopes.home_of(drone)
    if home is None or drone.lat is None or drone.lon is None:
        return Result("envelope", None, None, False, "no position: the envelope has no home")
    try:
        # The geofence is the organisation's; a drone's own limits lower only heights and
        # distances from home, which a drone standing at its home keeps.
        breach = env.fence_breach(_organisation_envelope(drone, cache), (drone.lat, drone.lon))
    except env.EnvelopeError as exc:
        return Result("envelope", None, None, False, f"envelope invalid: {exc}")
    value = {"home": list(home), "inside": breach is None}
    if breach is not None:
        return Result("envelope", None, value, False, breach)
    return Result("envelope", None, value, True)


def _zones(drone: Drone, threshold: float, cache: dict) -> Result:
    """No published zone refuses a take-off from where the drone stands to `threshold`
    metres (the check every command meets, fleet/envelopes.py)."""
    home = envelopes.home_of(drone)
    start = envelopes.position_ned(drone, home)
    if home is None or start is None:
        return Result("zones", threshold, None, False, "no position to check the zones at")
    move = env.Move("takeoff", (start[0], start[1], -threshold))
    found = envelopes.published_zones("move")(drone.organisation, home, move, start, False)
    value = {"zone": None if found is None else found.message}
    return Result("zones", threshold, value, found is None, "" if found is None else found.message)


def _remote_id(drone: Drone, threshold: None, cache: dict) -> Result:
    reasons = [r for check in REMOTE_ID_REASONS if (r := check(drone)) is not None]
    return Result("remote_id", None, {"reasons": reasons}, not reasons, "; ".join(reasons))


def _wind(drone: Drone, threshold: None, cache: dict) -> Result:
    """The flight controller's wind estimate within the drone's limit (fleet/wind.py)."""
    found = wind.reported(drone)
    if found is None:
        return Result("wind", None, None, False, "no wind estimate reported")
    value = {"speed": found["speed"], "limit": wind.effective_limit(drone)}
    why = wind.refusal(drone)
    return Result("wind", None, value, why is None, why or "")


def _airworthy(drone: Drone, threshold: None, cache: dict) -> Result:
    """The airworthiness verdict, the one a batch judged (`cache["verdicts"]`, by pk)
    where it did."""
    found = cache.get("verdicts", {}).get(drone.pk) or airworthiness.verdict(drone)
    return Result("airworthy", None, found.to_dict(), found.airworthy, "; ".join(found.reasons))


MEASURES: dict[str, Callable[[Drone, Any, dict], Result]] = {
    "gps": _gps,
    "battery": _battery,
    "link": _link,
    "envelope": _envelope,
    "zones": _zones,
    "remote_id": _remote_id,
    "wind": _wind,
    "airworthy": _airworthy,
}


def measure(drone: Drone, item: dict, cache: dict | None = None) -> Result:
    """One automatic item of a template, measured now. `cache` carries what drones of a
    batch share (their organisation's parsed envelope, the batch's airworthiness
    `verdicts`) from one drone to the next."""
    return MEASURES[item["check"]](drone, item["threshold"], {} if cache is None else cache)


def automatic_failures(drone: Drone, items: list[dict], cache: dict | None = None) -> list[str]:
    """Why the drone fails the automatic items (empty: it passes them all)."""
    found = (measure(drone, item, cache) for item in items if item["kind"] == "auto")
    return [f"{CHECKS[r.check].label}: {r.why}" for r in found if not r.passed]
