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
