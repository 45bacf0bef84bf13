"""Watching the ground itself: the health check and the status page's counters."""

from __future__ import annotations

from config.env import env

# /health runs its checks at most this often per web process (anyone may ask it).
HEALTH_CACHE_S = env.float("HEALTH_CACHE_S", 3.0)
# The status page's counters (workers/counters.py): a process whose heartbeat is older
# than INSTANCE_TTL_S is gone (several missed flushes, so one slow Redis round trip does
# not flap it); refusals are kept per drone for at most REFUSAL_DRONES drone ids, later
# ones counted together, so a flood of invented ids cannot grow Redis.
INSTANCE_TTL_S = env.float("INSTANCE_TTL_S", 10.0)
REFUSAL_DRONES = env.int("REFUSAL_DRONES", 1000)
