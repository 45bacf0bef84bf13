"""Traffic relay: with each live-separation pass, every airborne drone is told the other
airborne drones of its airspace nearby and its own reservation's altitude band, on
`<id>/traffic/in` (docs/protocol.md "Traffic"); the agent keeps a last-resort check of its
own from them (onboard/traffic.py).

Heights are heights above each drone's own home, compared as they are (the rule of the
ground's own live check: the homes of one airspace are taken at one elevation). Cost: one
message per airborne drone per pass, each with at most `AIRSPACE_TRAFFIC_MAX` drones, the
nearest within `AIRSPACE_TRAFFIC_RANGE_M`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from django.conf import settings

from fleet.models import Drone
from onboard.traffic import Other, traffic_message
from workers import outbox

from .models import Reservation

# A relayed picture is worth nothing after the agent's own stale age (onboard/traffic.py
# STALE_S): the outbox drops what its gateway has not sent by then.
TTL_S = 3.0


def bands_of(drones: Sequence[Drone]) -> dict[str, tuple[float, float]]:
    """Each drone's altitude band over its active reservations: the lowest low and the
    highest high of their legs (metres above home)."""
    ids = {d.pk: d.drone_id for d in drones}
    bands: dict[str, tuple[float, float]] = {}
    rows = Reservation.objects.filter(drone__in=list(drones), ended_at__isnull=True)
    for drone_pk, legs in rows.values_list("drone_id", "legs"):
        if not legs:
            continue
        low = min(float(leg[4]) for leg in legs)
        high = max(float(leg[5]) for leg in legs)
        was = bands.get(ids[drone_pk])
        bands[ids[drone_pk]] = (low, high) if was is None else (min(was[0], low), max(was[1], high))
    return bands


def neighbours(tracks: Sequence, limit: int, range_m: float) -> list[list[int]]:
    """For each track, the indices of the others within `range_m` horizontally, the
    nearest first, at most `limit`."""
    if not tracks:
        return []
    xy = np.array([[t.x, t.y] for t in tracks])
    apart = np.hypot(xy[:, None, 0] - xy[None, :, 0], xy[:, None, 1] - xy[None, :, 1])
    np.fill_diagonal(apart, np.inf)
    out = []
    for row in apart:
        order = np.argsort(row, kind="stable")[:limit]
        out.append([int(k) for k in order if row[k] <= range_m])
    return out


def relay(drones: Sequence[Drone], tracks: Sequence, now: float) -> int:
    """Send every drone of one airspace its traffic and band; how many messages."""
    bands = bands_of(drones)
    near = neighbours(tracks, settings.AIRSPACE_TRAFFIC_MAX, settings.AIRSPACE_TRAFFIC_RANGE_M)
    by_id = {d.drone_id: d for d in drones}
    for track, others in zip(tracks, near, strict=True):
        entries = []
        for k in others:
            o = tracks[k]
            drone = by_id[o.drone_id]
            entries.append(
                Other(
                    o.drone_id,
                    drone.lat,
                    drone.lon,
                    o.z,
                    o.vx,
                    o.vy,
                    o.vz,  # type: ignore[arg-type]
                    max(track.horizontal_min_m, o.horizontal_min_m),
                    max(track.vertical_min_m, o.vertical_min_m),
                )  # fmt: skip
            )
        message = traffic_message(now, bands.get(track.drone_id), entries)
        outbox.send_to_drone(track.drone_id, "traffic", message, ttl=TTL_S)
    return len(tracks)
