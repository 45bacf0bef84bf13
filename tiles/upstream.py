"""The optional pass-through cache: a tile missing locally is fetched once from
TILE_UPSTREAM_URL (off by default) and kept in TILES_DIR/cache for every later request,
so an area looked at once with internet stays on the map in the field."""

from __future__ import annotations

import logging
import urllib.error
import urllib.request
from pathlib import Path

from django.conf import settings

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
    return store.tile_path(store.cache_dir(), z, x, y, ext)
