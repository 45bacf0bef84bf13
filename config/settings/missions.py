"""Missions: planning limits, choosing drones, replacements, panic calls."""

from __future__ import annotations

from config.env import env

# Coverage requests above this many waypoints are refused, so one request cannot tie up a worker.
MISSIONS_MAX_WAYPOINTS = env.int("MISSIONS_MAX_WAYPOINTS", 50_000)
# Survey estimates: cruise speed between photos, and the flight time of a full battery for
# a drone whose gear does not state its ENDURANCE_MIN.
MISSIONS_SURVEY_SPEED_M_S = env.float("MISSIONS_SURVEY_SPEED_M_S", 5.0)
MISSIONS_SURVEY_ENDURANCE_MIN = env.float("MISSIONS_SURVEY_ENDURANCE_MIN", 20.0)
# A drone at or below this battery fraction is never chosen for a mission.
MISSIONS_BATTERY_RESERVE = env.float("MISSIONS_BATTERY_RESERVE", 0.3)
# Drones brought in by an OUT_MEASURE alarm: two, as in the collaborative-sensing
# experiment of [Paula 2018], §5.4.
MISSIONS_JOINING_DRONES = env.int("MISSIONS_JOINING_DRONES", 2)
# A mission start not published by a gateway within this long is dropped as stale.
MISSIONS_START_TTL_S = env.float("MISSIONS_START_TTL_S", 60.0)
# Paused missions (no drone to replace a failing one) look for a drone this often, and a
# panic call's drone down to MISSIONS_BATTERY_RESERVE on station is relieved as often.
MISSIONS_RESUME_INTERVAL_S = env.float("MISSIONS_RESUME_INTERVAL_S", 5.0)
# The panic button's hover altitude: 10 m, as in the panic-button experiment of
# [Paula 2018], §5.1.
MISSIONS_PANIC_ALTITUDE = env.float("MISSIONS_PANIC_ALTITUDE", 10.0)
# A drone that goes offline mid-mission is replaced when still offline this long after.
MISSIONS_OFFLINE_GRACE_S = env.float("MISSIONS_OFFLINE_GRACE_S", 30.0)
