"""Published UAS geographical zones: what an imported file may hold, and how the fleet
app reaches the zones' checks (it may not import the zones app, which builds on it)."""

from __future__ import annotations

from config.env import env

# One zone file, read whole into memory: bytes, zones (ED-269 volumes count one each) and
# vertices in all. A national ED-269 file is a few thousand zones.
ZONES_MAX_FILE_BYTES = env.int("ZONES_MAX_FILE_BYTES", 20 * 1024 * 1024)
ZONES_MAX_ZONES = env.int("ZONES_MAX_ZONES", 10_000)
ZONES_MAX_VERTICES = env.int("ZONES_MAX_VERTICES", 200_000)
# The functions fleet/envelopes.py calls for every command and mission step.
PUBLISHED_ZONE_CHECKS = {
    "move": "zones.enforcement.move_violation",
    "steps": "zones.enforcement.step_violations",
}
# `GET /api/v1/zones/` answers at most this many zones (ask for a smaller bbox).
ZONES_LIST_LIMIT = env.int("ZONES_LIST_LIMIT", 2000)
