"""Airspace: reservations and the separation minima between the platform's own drones
(docs/airspace.md, "Separation")."""

from __future__ import annotations

from config.env import env

# Separation minima: two drones' corridors must stay this far apart horizontally (metres
# between the corridors' edges) unless their altitude bands are this far apart vertically.
# The platform's own numbers for small drones (ICAO's rule, not its distances for manned
# aircraft: [ICAO Doc 4444], ch. 5); an organisation may set its own (admin).
AIRSPACE_HORIZONTAL_MIN_M = env.float("AIRSPACE_HORIZONTAL_MIN_M", 30.0)
AIRSPACE_VERTICAL_MIN_M = env.float("AIRSPACE_VERTICAL_MIN_M", 10.0)
# One airspace for the whole site: every organisation's flights are checked against every
# other's (each pair held to the larger of its two organisations' minima).
AIRSPACE_SITE_WIDE = env.bool("AIRSPACE_SITE_WIDE", False)
# A corridor's horizontal radius and a band's widening: the tolerance within which a drone
# counts as on its waypoint (onboard/protocol.py DEFAULT_TOLERANCE, [Paula 2018] algorithm 1).
AIRSPACE_CORRIDOR_RADIUS_M = env.float("AIRSPACE_CORRIDOR_RADIUS_M", 2.0)
AIRSPACE_VERTICAL_TOLERANCE_M = env.float("AIRSPACE_VERTICAL_TOLERANCE_M", 2.0)
# Speeds a flight's time windows are computed with: the cruise speed of a drone whose gear
# states no CRUISE_SPEED_M_S (as the survey estimates assume), and the climb rate.
AIRSPACE_CRUISE_SPEED_M_S = env.float("AIRSPACE_CRUISE_SPEED_M_S", 5.0)
AIRSPACE_CLIMB_SPEED_M_S = env.float("AIRSPACE_CLIMB_SPEED_M_S", 2.0)
# A leg's window opens this much before its nominal start, shrunk by the early factor (0.5:
# the drone twice as fast), and closes this much after its nominal end, stretched by the
# slack (0.5: the drone half as slow again).
AIRSPACE_TIME_BUFFER_S = env.float("AIRSPACE_TIME_BUFFER_S", 30.0)
AIRSPACE_TIME_EARLY = env.float("AIRSPACE_TIME_EARLY", 0.5)
AIRSPACE_TIME_SLACK = env.float("AIRSPACE_TIME_SLACK", 0.5)
# How long a drone is assumed to hover after its last step or command, and how long an
# airborne drone with no plan known holds the column under it.
AIRSPACE_HOLD_S = env.float("AIRSPACE_HOLD_S", 300.0)
# What fleet/envelopes.py calls for a command (named, not imported: fleet sits below).
AIRSPACE_COMMAND_CHECK = "airspace.separation.check_command"
AIRSPACE_COMMAND_RESERVE = "airspace.separation.reserve_command"
# A drone's pace (fleet/envelopes.py: its legs flown while climbing, for the terrain).
AIRSPACE_PACE = "airspace.reservations.pace_for"
# Live separation (airspace/live.py): how often the ground looks at its airborne drones,
# how far ahead it flies them on at their velocity and in what steps, how old a previous
# fix may be to give a velocity, and how long a held pair is not held again.
AIRSPACE_LIVE_INTERVAL_S = env.float("AIRSPACE_LIVE_INTERVAL_S", 1.0)
AIRSPACE_LIVE_HORIZON_S = env.float("AIRSPACE_LIVE_HORIZON_S", 10.0)
AIRSPACE_LIVE_STEP_S = env.float("AIRSPACE_LIVE_STEP_S", 0.5)
AIRSPACE_LIVE_FIX_S = env.float("AIRSPACE_LIVE_FIX_S", 5.0)
AIRSPACE_LIVE_REPEAT_S = env.float("AIRSPACE_LIVE_REPEAT_S", 30.0)
# The landing queue over home (airspace/landing.py): what fleet/commands.py calls for the
# operator's `return` and its answer, how often the queue gives the next drone its turn,
# how close over home a holding drone must be to be told to land (the waypoint tolerance,
# [Paula 2018] algorithm 1, plus a metre for the position's noise: the platform's own), and
# after how long a landing drone still in the air is told to land again.
AIRSPACE_RETURN_ROUTE = "airspace.landing.route_return"
AIRSPACE_RETURN_ANSWERED = "airspace.landing.return_answered"
AIRSPACE_LANDING_INTERVAL_S = env.float("AIRSPACE_LANDING_INTERVAL_S", 1.0)
AIRSPACE_LANDING_OVER_HOME_M = env.float("AIRSPACE_LANDING_OVER_HOME_M", 3.0)
AIRSPACE_LANDING_RESEND_S = env.float("AIRSPACE_LANDING_RESEND_S", 10.0)
# A holding drone that in this long neither was near its hold nor came the over-home
# tolerance nearer to it is sent its hold again, at most this many times per queue place
# (then it leaves the queue): a drone flying to its hold at the climb rate covers 20 m in
# that time, a hovering one its position's noise (the platform's own numbers).
AIRSPACE_LANDING_HOLD_RESEND_S = env.float("AIRSPACE_LANDING_HOLD_RESEND_S", 10.0)
AIRSPACE_LANDING_HOLD_RESENDS = env.int("AIRSPACE_LANDING_HOLD_RESENDS", 5)
# What the operator's `return` calls to stop the drone's mission parts first (named, not
# imported: missions sits above airspace).
AIRSPACE_RETURN_STOPS_MISSION = "missions.returning.stop_for_return"
# Staggered departures of the platform's own plans (airspace/separation.py): when no
# altitude layer is clear, a drone that takes off waits on the ground before it arms, the
# shortest multiple of the step after which a layer is clear, up to the maximum (the
# platform's own numbers: about the length of a small survey).
AIRSPACE_STAGGER_STEP_S = env.float("AIRSPACE_STAGGER_STEP_S", 10.0)
AIRSPACE_STAGGER_MAX_S = env.float("AIRSPACE_STAGGER_MAX_S", 600.0)
