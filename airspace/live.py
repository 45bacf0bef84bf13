"""Live separation: the ground watches where its drones actually are and, when two are
predicted within the separation minima in the next seconds, holds one of them.

Prediction: each airborne drone's last two reported positions give its velocity; both
drones are flown on in a straight line at that velocity for `AIRSPACE_LIVE_HORIZON_S`
(10 s), sampled every `AIRSPACE_LIVE_STEP_S` (0.5 s). A pair is predicted to lose
separation when at one sampled moment they are closer than the horizontal minimum and
closer than the vertical minimum (airspace/index.py states the rule; the pair keeps the
larger of its two organisations' minima). A fix older than `AIRSPACE_LIVE_FIX_S` gives no
velocity (the drone is taken as still).

Priority, first come first served as reservations are granted: the drone whose active
reservation is the older keeps flying; the other holds. A drone flying without any
reservation holds before one with a reservation; between two without, the one whose id
sorts last. The hold: a drone flying a mission gets the mission's pause (it hovers where
it is and carries on when resumed, docs/protocol.md); any other drone a `navigate` to
where it is. Each hold raises one CRITICAL alert (the alerts app, through
`separation_lost`), and a pair is held at most once per `AIRSPACE_LIVE_REPEAT_S`.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from django.conf import settings
from django.core.cache import cache

from fleet.models import Drone
from onboard import protocol
from workers import outbox

from . import reservations, traffic
from .corridors import EARTH_RADIUS
from .models import Reservation
from .signals import separation_lost

_FIX_KEY = "airspace:fix:{}"
_HELD_KEY = "airspace:held:{}:{}"


@dataclass(frozen=True)
class Track:
    """A drone's position (local metres east, north, up) and velocity (m/s)."""

    drone_id: str
    x: float
    y: float
    z: float
    vx: float
    vy: float
    vz: float
    horizontal_min_m: float
    vertical_min_m: float


@dataclass(frozen=True)
class Loss:
    """Two drones predicted within the minima `in_s` seconds from now."""

    a: Track
    b: Track
    in_s: float
    horizontal_m: float
    vertical_m: float


def predicted_losses(tracks: Sequence[Track], horizon_s: float, step_s: float) -> list[Loss]:
    """Every pair of tracks predicted within the minima within `horizon_s`, the earliest
    moment each; all pairs and moments at once with numpy."""
    if len(tracks) < 2:
        return []
    cols = np.array(
        [[t.x, t.y, t.z, t.vx, t.vy, t.vz, t.horizontal_min_m, t.vertical_min_m] for t in tracks]
    )
    i, j = np.triu_indices(len(tracks), k=1)
    # Only pairs that can close the distance within the horizon are flown on.
    speed = np.hypot(cols[:, 3], cols[:, 4])
    now_apart = np.hypot(cols[j, 0] - cols[i, 0], cols[j, 1] - cols[i, 1])
    reach = np.maximum(cols[i, 6], cols[j, 6]) + (speed[i] + speed[j]) * horizon_s
    near = now_apart < reach
    i, j = i[near], j[near]
    moments = np.arange(0.0, horizon_s + step_s / 2, step_s)
    rel = cols[j, :6] - cols[i, :6]
    dx = rel[:, 0, None] + rel[:, 3, None] * moments
    dy = rel[:, 1, None] + rel[:, 4, None] * moments
    dz = rel[:, 2, None] + rel[:, 5, None] * moments
    horizontal, vertical = np.hypot(dx, dy), np.abs(dz)
    hmin = np.maximum(cols[i, 6], cols[j, 6])[:, None]
    vmin = np.maximum(cols[i, 7], cols[j, 7])[:, None]
    lost = (horizontal < hmin) & (vertical < vmin)
    losses = []
    for k in np.flatnonzero(lost.any(axis=1)):
        m = int(np.argmax(lost[k]))
        losses.append(
            Loss(
                tracks[i[k]],
                tracks[j[k]],
                float(moments[m]),
                float(horizontal[k, m]),
                float(vertical[k, m]),
            )  # fmt: skip
        )
    return losses


def _local(lat: float, lon: float, origin: tuple[float, float]) -> tuple[float, float]:
    north = math.radians(lat - origin[0]) * EARTH_RADIUS
    east = math.radians(lon - origin[1]) * EARTH_RADIUS * math.cos(math.radians(origin[0]))
    return east, north


def _velocity(drone: Drone, now: float, origin: tuple[float, float]) -> tuple[float, float, float]:
    """From the fix remembered at the previous watch; the current one is remembered."""
    key = _FIX_KEY.format(drone.drone_id)
    before = cache.get(key)
    fix = (now, drone.lat, drone.lon, drone.alt or 0.0)
    cache.set(key, fix, timeout=max(60, int(settings.AIRSPACE_LIVE_FIX_S * 4)))
    if not before or not 0 < now - before[0] <= settings.AIRSPACE_LIVE_FIX_S:
        return 0.0, 0.0, 0.0
    x0, y0 = _local(before[1], before[2], origin)
    x1, y1 = _local(drone.lat, drone.lon, origin)  # type: ignore[arg-type]
    dt = now - before[0]
    return (x1 - x0) / dt, (y1 - y0) / dt, (fix[3] - before[3]) / dt


def tracks_of(drones: Sequence[Drone], now: float) -> list[Track]:
    if not drones:
        return []
    origin = (drones[0].lat, drones[0].lon)
    out = []
    for drone in drones:
        x, y = _local(drone.lat, drone.lon, origin)  # type: ignore[arg-type]
        vx, vy, vz = _velocity(drone, now, origin)  # type: ignore[arg-type]
        horizontal, vertical = reservations.minima_for(drone.organisation_id)
        out.append(Track(drone.drone_id, x, y, drone.alt or 0.0, vx, vy, vz, horizontal, vertical))
    return out


def _priority(drone_id: str, held: dict[str, Reservation]) -> tuple:
    """Sorts the drone that keeps flying first: an older reservation, then any."""
    row = held.get(drone_id)
    return (row is None, row.created_at.timestamp() if row else 0.0, drone_id)


def hold(drone: Drone, reservation: Reservation | None) -> str:
    """Hold the drone where it is; what was sent."""
    if reservation is not None and reservation.assignment_id is not None:
        mission_id = str(reservation.assignment.mission_id)
        message = protocol.mission_pause(mission_id, "pause").to_dict()
        outbox.send_to_drone(drone.drone_id, "mission", {**message, "ts": protocol.now()})
        return "mission pause"
    params = {"lat": drone.lat, "lon": drone.lon}
    request = protocol.control_request("navigate", params)
    outbox.send_to_drone(drone.drone_id, "control", request.to_dict())
    return "navigate to where it is"


def _airspaces() -> list[list[Drone]]:
    airborne = list(
        Drone.objects.filter(airborne=True, online=True, lat__isnull=False, lon__isnull=False)
        .select_related("organisation")
        .order_by("organisation_id", "drone_id")
    )
    if settings.AIRSPACE_SITE_WIDE:
        return [airborne]
    groups: dict[int, list[Drone]] = {}
    for drone in airborne:
        groups.setdefault(drone.organisation_id, []).append(drone)
    return list(groups.values())


def _once(loser: str, winner: str) -> bool:
    """True the first time this pair is held within AIRSPACE_LIVE_REPEAT_S."""
    key = _HELD_KEY.format(*sorted((loser, winner)))
    return cache.add(key, 1, timeout=max(1, int(settings.AIRSPACE_LIVE_REPEAT_S)))


def watch() -> list[str]:
    """One look at every airspace: relay each airborne drone its traffic, and hold the
    lower-priority drone of each pair predicted to lose separation (unless
    AIRSPACE_LIVE_HOLD is off). The ids of the drones held."""
    now = time.time()
    reservations.sweep()
    held_ids = []
    for drones in _airspaces():
        tracks = tracks_of(drones, now)
        traffic.relay(drones, tracks, now)
        if not settings.AIRSPACE_LIVE_HOLD:
            continue
        losses = predicted_losses(
            tracks, settings.AIRSPACE_LIVE_HORIZON_S, settings.AIRSPACE_LIVE_STEP_S
        )
        if not losses:
            continue
        by_id = {d.drone_id: d for d in drones}
        ids = {d.pk: d.drone_id for d in drones}
        rows = Reservation.objects.filter(drone__in=drones, ended_at__isnull=True)
        held = {ids[r.drone_id]: r for r in rows.select_related("assignment")}
        for loss in losses:
            winner, loser = sorted(
                (loss.a.drone_id, loss.b.drone_id), key=lambda d: _priority(d, held)
            )
            if not _once(loser, winner):
                continue
            how = hold(by_id[loser], held.get(loser))
            separation_lost.send(
                Drone, drone=by_id[loser], other=by_id[winner], in_s=loss.in_s,
                horizontal_m=loss.horizontal_m, vertical_m=loss.vertical_m, action=how,
            )  # fmt: skip
            held_ids.append(loser)
    return held_ids
