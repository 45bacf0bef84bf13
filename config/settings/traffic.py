"""Traffic relayed to the drones for their own last-resort separation check
(airspace/traffic.py, onboard/traffic.py; docs/airspace.md "Live separation")."""

from __future__ import annotations

from config.env import env

# Each live-separation pass relays to every airborne drone the other airborne drones of
# its airspace within this many metres horizontally, the nearest first and at most this
# many (a message's cost is bounded: one per airborne drone per pass, each at most
# AIRSPACE_TRAFFIC_MAX entries). The range covers two drones closing at 2 × 25 m/s for the
# ground's 10 s horizon plus the 30 m minimum, with room.
AIRSPACE_TRAFFIC_RANGE_M = env.float("AIRSPACE_TRAFFIC_RANGE_M", 600.0)
AIRSPACE_TRAFFIC_MAX = env.int("AIRSPACE_TRAFFIC_MAX", 8)
# Whether the ground itself holds a drone predicted to lose separation (airspace/live.py).
# Off only to see the drones' own check act alone (tests, trials); traffic is relayed
# either way.
AIRSPACE_LIVE_HOLD = env.bool("AIRSPACE_LIVE_HOLD", True)
