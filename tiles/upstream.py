"""The optional pass-through cache: a tile missing locally is fetched once from
TILE_UPSTREAM_URL (off by default) and kept in TILES_DIR/cache for every later request,
so an area looked at once with internet stays on the map in the field.

What a user can make the server fetch and keep is bounded (`refusal`): only members of an
organisation; at zooms up to TILE_UPSTREAM_OVERVIEW_ZOOM anywhere (enough to find one's
way on the map), above it up to TILE_UPSTREAM_MAX_ZOOM only tiles that touch where their
organisations may fly: the envelope's inclusion zones, else the circle of its maximum
distance about the envelope's home and each drone's home (fleet/envelopes.py). The cache
holds at most TILE_CACHE_MAX_BYTES: past it the least recently served tiles go
(`keep_within_cap`); a served tile's access time is set on each use (`touch`), explicitly,
so this holds on filesystems mounted noatime.
"""

from __future__ import annotations

import logging
import os
import time
import urllib.error
import urllib.request
from pathlib import Path
from typing import Any

from django.conf import settings
from django.core.cache import cache

from fleet import envelopes
from fleet.models import Drone, Organisation
from onboard import envelope as env
from tiles import store
from tiles.sources import MAX_TILE_BYTES

logger = logging.getLogger(__name__)

# Tile servers ask for an identifying User-Agent (the OpenStreetMap tile usage policy).
USER_AGENT = "Skyhive ground station (tile cache)"


class UpstreamError(Exception):
    """The online source failed or sent something that is not a tile."""


def upstream_url(z: int, x: int, y: int) -> str:
    template: str = settings.TILE_UPSTREAM_URL
    return template.replace("{z}", str(z)).replace("{x}", str(x)).replace("{y}", str(y))


Box = tuple[float, float, float, float]  # west, south, east, north (degrees)
# Eviction brings the cache down to this share of its cap, so it does not run per tile.
LOW_WATER = 0.9


def refusal(user: Any, z: int, x: int, y: int) -> str | None:
    """Why `user` may not have tile z/x/y fetched from the source; None when they may."""
    if z > int(settings.TILE_UPSTREAM_MAX_ZOOM):
        return f"zoom {z} is above TILE_UPSTREAM_MAX_ZOOM"
    organisations = Organisation.objects.filter(memberships__user=user) if user.is_authenticated else Organisation.objects.none()  # fmt: skip
    if not organisations:
        return "only members of an organisation have tiles fetched"
    if z <= int(settings.TILE_UPSTREAM_OVERVIEW_ZOOM):
        return None
    tile = store.tile_bounds(z, x, y)
    if any(_overlap(tile, box) for org in organisations for box in envelope_boxes(org)):
        return None
    return "the tile is outside the flight envelopes of the user's organisations"


def envelope_boxes(organisation: Organisation) -> list[Box]:
    """Where the organisation's drones may fly, as boxes: the envelope's inclusion zones,
    else its maximum distance about the envelope's home and about each drone's home."""
    envelope = envelopes.organisation_envelope(organisation)
    if envelope.has_inclusion:
        boxes = [_points_box(p.points) for p in envelope.polygons if p.inclusion]
        return boxes + [_circle_box(c.center, c.radius) for c in envelope.circles if c.inclusion]
    homes = [(organisation.envelope or {}).get("home")]
    homes += [envelopes.home_of(d) for d in Drone.objects.filter(organisation=organisation)]
    return [_circle_box(h, envelope.max_distance) for h in homes if h and len(h) >= 2]


def _points_box(points: Any) -> Box:
    lats, lons = [p[0] for p in points], [p[1] for p in points]
    return min(lons), min(lats), max(lons), max(lats)


def _circle_box(center: Any, radius: float) -> Box:
    home = (float(center[0]), float(center[1]))
    south, west = env.ned_to_latlon(-radius, -radius, home)
    north, east = env.ned_to_latlon(radius, radius, home)
    return west, south, east, north


def _overlap(a: Box, b: Box) -> bool:
    return a[0] <= b[2] and b[0] <= a[2] and a[1] <= b[3] and b[1] <= a[3]


def touch(path: Path) -> None:
    """Mark a cached tile as just used (its access time; the modification time, which the
    ETag is made of, stays)."""
    try:
        os.utime(path, (time.time(), path.stat().st_mtime))
    except FileNotFoundError:
        pass  # evicted meanwhile


def _usage_key() -> str:
    return f"tiles:cache-bytes:{store.cache_dir()}"


def keep_within_cap(added: int = 0) -> int:
    """Count `added` bytes into the cache; past TILE_CACHE_MAX_BYTES, delete the least
    recently used tiles down to LOW_WATER of it. Returns how many went."""
    cap = int(settings.TILE_CACHE_MAX_BYTES)
    try:
        total = cache.incr(_usage_key(), added)
    except ValueError:  # not counted yet (or Redis was flushed): count the folder
        total = cap + 1
    if total <= cap or not cache.add(_usage_key() + ":lock", 1, 60):
        return 0
    try:
        return _evict(cap)
    finally:
        cache.delete(_usage_key() + ":lock")


def _evict(cap: int) -> int:
    tiles = []
    for path in store.cache_dir().rglob("*.*"):
        try:
            stat = path.stat()
        except FileNotFoundError:
            continue
        tiles.append((stat.st_atime, stat.st_size, path))
    total = sum(size for _, size, _ in tiles)
    removed = 0
    for _, size, path in sorted(tiles) if total > cap else []:
        if total <= cap * LOW_WATER:
            break
        path.unlink(missing_ok=True)
        total -= size
        removed += 1
    cache.set(_usage_key(), total, None)
    return removed


def fetch_and_keep(z: int, x: int, y: int) -> Path | None:
    """The cached tile after fetching it; None when the source has no such tile (404)."""
    request = urllib.request.Request(upstream_url(z, x, y), headers={"User-Agent": USER_AGENT})
    timeout = float(settings.TILE_UPSTREAM_TIMEOUT_S)
    try:
        with urllib.request.urlopen(request, timeout=timeout) as response:  # noqa: S310
            data = response.read(MAX_TILE_BYTES + 1)
    except urllib.error.HTTPError as exc:
        if exc.code == 404:
            return None
        raise UpstreamError(f"tile source answered {exc.code}") from exc
    except (OSError, ValueError) as exc:
        raise UpstreamError(f"tile source unreachable: {exc}") from exc
    if len(data) > MAX_TILE_BYTES or store.sniff_format(data) is None:
        raise UpstreamError("tile source sent something that is not a PNG, JPEG or WebP tile")
    ext = store.write_tile(store.cache_dir(), z, x, y, data)
    keep_within_cap(len(data))
    return store.tile_path(store.cache_dir(), z, x, y, ext)
