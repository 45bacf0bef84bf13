"""Terrain: imported elevation models and the minimum clearance above them."""

from __future__ import annotations

from config.env import env

from .core import DATA_DIR
from .security import REQUEST_BODY_LIMITS

# Imported grids (manage.py import_terrain, the admin), one .npy file per tile.
TERRAIN_DIR = env.str("TERRAIN_DIR", f"{DATA_DIR}/terrain")
# The admin's upload: an SRTM 1 arc-second tile is 25 MB, a ZIP of a region's tiles more.
TERRAIN_UPLOAD_MAX_BYTES = env.int("TERRAIN_UPLOAD_MAX_BYTES", 512 * 1024**2)
# One import (upload, command, folder or ZIP): files, bytes unpacked in all and per file,
# and samples per grid (a 1 arc-second SRTM tile is 3601 x 3601 = 13 million; each sample
# is held as 4 bytes while it is checked).
TERRAIN_IMPORT_MAX_FILES = env.int("TERRAIN_IMPORT_MAX_FILES", 200)
TERRAIN_IMPORT_MAX_BYTES = env.int("TERRAIN_IMPORT_MAX_BYTES", 8 * 1024**3)
TERRAIN_FILE_MAX_BYTES = env.int("TERRAIN_FILE_MAX_BYTES", 256 * 1024**2)
TERRAIN_MAX_SAMPLES = env.int("TERRAIN_MAX_SAMPLES", 64 * 1024**2)
# The clearance every leg keeps above the terrain unless the organisation set its own
# (terrain/guard.py states the rule).
TERRAIN_MIN_CLEARANCE = env.float("TERRAIN_MIN_CLEARANCE", 30.0)
# Whether an organisation without its own choice also reads its envelope's maximum height
# above the terrain where terrain is imported (terrain/guard.py states the rule).
TERRAIN_CEILING_ABOVE_TERRAIN = env.bool("TERRAIN_CEILING_ABOVE_TERRAIN", False)
# The admin's terrain upload: its own limit plus a megabyte of multipart framing, refused
# past it before Django reads the body (config/bodylimits.py).
REQUEST_BODY_LIMITS.insert(
    0, (r"^/admin/terrain/terraintile/add/$", TERRAIN_UPLOAD_MAX_BYTES + 1024**2)
)
