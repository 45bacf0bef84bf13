"""Flight-log health checks and spectra: threshold overrides and the spectrum's cost bound."""

from __future__ import annotations

import json

from config.env import env

# Overrides of the checks' thresholds (logs/checks/thresholds.py), as JSON: keys "*"
# (every organisation), "<organisation slug>", and either with "/airframe:<id>" (PX4
# SYS_AUTOSTART, ArduPilot FRAME_CLASS) appended; each value names checks and numbers,
# e.g. {"acme": {"vibration": {"ardupilot": {"warning": 20}}}}. Checked when a log is.
LOGS_CHECK_THRESHOLDS = json.loads(env.str("LOGS_CHECK_THRESHOLDS", "{}") or "{}")
# One spectrum request averages at most this many Welch segments (each of `nperseg` <=
# 4096 samples), spread over the window, whatever the log's length.
LOGS_SPECTRUM_MAX_SEGMENTS = env.int("LOGS_SPECTRUM_MAX_SEGMENTS", 256)
# A drone's trends (logs/trends.py): a figure is flagged when it lies beyond
# LOGS_TREND_SIGMAS sample standard deviations of the mean of the drone's previous
# LOGS_TREND_HISTORY flights (judged once it has LOGS_TREND_MIN_HISTORY of them), or of
# the other drones' latest LOGS_TREND_HISTORY flights, on the worse side.
LOGS_TREND_HISTORY = env.int("LOGS_TREND_HISTORY", 10)
LOGS_TREND_MIN_HISTORY = env.int("LOGS_TREND_MIN_HISTORY", 5)
LOGS_TREND_SIGMAS = env.float("LOGS_TREND_SIGMAS", 3.0)
# Organisations (slugs, or "*" for all) whose drifting drones also get a maintenance item.
LOGS_TREND_MAINTENANCE = env.list("LOGS_TREND_MAINTENANCE", default=[])
# The dotted path of the function that opens a maintenance item on a drone, called with
# drone, title, detail and source (the same drift opens one item); empty: none is opened.
# The maintenance app's finding keeps the drone on the ground until an admin signs it off.
LOGS_TREND_MAINTENANCE_FUNCTION = env.str(
    "LOGS_TREND_MAINTENANCE_FUNCTION", "maintenance.findings.open_finding"
)
