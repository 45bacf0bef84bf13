"""Map tiles, offline first: imported sets, another tile server, or a kept online source."""

from __future__ import annotations

from config.env import env

from .core import DATA_DIR

# Another tile server for every map (like one on the site's own network); empty (the
# default) uses the portal's own tiles (/tiles/).
MAP_TILE_URL = env.str("MAP_TILE_URL", "")
MAP_TILE_ATTRIBUTION = env.str("MAP_TILE_ATTRIBUTION", "")
# Imported tile sets and the cache of the online source (manage.py import_tiles, the admin).
TILES_DIR = env.str("TILES_DIR", f"{DATA_DIR}/tiles")
TILES_UPLOAD_MAX_BYTES = env.int("TILES_UPLOAD_MAX_BYTES", 1024**3)
# One import (upload, command or ZIP) holds at most this many tiles and bytes unpacked
# (tiles/sources.py; a city at zoom 18 is about 100 000 tiles).
TILES_IMPORT_MAX_TILES = env.int("TILES_IMPORT_MAX_TILES", 200_000)
TILES_IMPORT_MAX_BYTES = env.int("TILES_IMPORT_MAX_BYTES", 4 * 1024**3)
# Browsers keep a served tile this long before asking again (then 304 when unchanged).
TILE_CACHE_MAX_AGE_S = env.int("TILE_CACHE_MAX_AGE_S", 7 * 86400)
# An online tile source (like https://tile.openstreetmap.org/{z}/{x}/{y}.png) the portal
# fetches missing tiles from and keeps: off by default, nothing leaves the server.
TILE_UPSTREAM_URL = env.str("TILE_UPSTREAM_URL", "")
TILE_UPSTREAM_ATTRIBUTION = env.str(
    "TILE_UPSTREAM_ATTRIBUTION", "&copy; OpenStreetMap contributors"
)
TILE_UPSTREAM_TIMEOUT_S = env.float("TILE_UPSTREAM_TIMEOUT_S", 5.0)
# What users can have fetched and kept (tiles/upstream.py): members of an organisation
# only; any tile up to the overview zoom, above it only tiles touching where their
# organisations may fly, up to the source's last zoom (19 on OpenStreetMap's servers).
TILE_UPSTREAM_OVERVIEW_ZOOM = env.int("TILE_UPSTREAM_OVERVIEW_ZOOM", 6)
TILE_UPSTREAM_MAX_ZOOM = env.int("TILE_UPSTREAM_MAX_ZOOM", 19)
# The cache's cap: past it the least recently served tiles are deleted.
TILE_CACHE_MAX_BYTES = env.int("TILE_CACHE_MAX_BYTES", 1024**3)
