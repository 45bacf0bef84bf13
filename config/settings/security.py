"""What bounds a request before any view runs: body sizes, uploads, rates and sign-in
guessing (docs/security.md)."""

from __future__ import annotations

from config.env import env

from .zones import ZONES_MAX_FILE_BYTES

AUTH_PASSWORD_VALIDATORS = [
    {"NAME": "django.contrib.auth.password_validation.UserAttributeSimilarityValidator"},
    {"NAME": "django.contrib.auth.password_validation.MinimumLengthValidator"},
    {"NAME": "django.contrib.auth.password_validation.CommonPasswordValidator"},
    {"NAME": "django.contrib.auth.password_validation.NumericPasswordValidator"},
]

# Uploads are streamed to disk (never held in memory) beyond this size.
FILE_UPLOAD_MAX_MEMORY_SIZE = 2 * 1024 * 1024
# Form fields (not files) of one request: the largest non-file body any address takes
# (a mission of MISSIONS_MAX_WAYPOINTS steps), and no more fields or files than a form has.
DATA_UPLOAD_MAX_MEMORY_SIZE = 16 * 1024 * 1024
DATA_UPLOAD_MAX_NUMBER_FIELDS = 1000
DATA_UPLOAD_MAX_NUMBER_FILES = 10
# Uploads one user may have under way at once at each upload address (config/uploadgate.py).
UPLOAD_MAX_CONCURRENT = env.int("UPLOAD_MAX_CONCURRENT", 2)
# Request bodies (config/bodylimits.py): HTTP 413 past these, before any view runs. The
# first matching pattern wins; None leaves the limit to the endpoint itself.
REQUEST_BODY_MAX_BYTES = env.int("REQUEST_BODY_MAX_BYTES", 1024 * 1024)
REQUEST_BODY_LIMITS = [
    # The admin's map-tile upload has its own limit (TILES_UPLOAD_MAX_BYTES, config/asgi.py).
    (r"^/admin/tiles/tileset/add/$", None),
    # A published zone file (ZONES_MAX_FILE_BYTES, zones/admin.py) and its multipart framing.
    (r"^/admin/zones/zone/import/$", ZONES_MAX_FILE_BYTES + 64 * 1024),
    # Flight logs stream to disk with their own limit (LOG_UPLOAD_MAX_BYTES, logs/asgi.py).
    (r"^/api/v1/logs/$", None),
    # A mission log to view (missions/logs.py reads up to 50 MiB) and its multipart framing.
    (r"^/api/v1/missions/logs/check/$", 51 * 1024 * 1024),
    # Missions with their steps, QGroundControl plans and envelope checks of a mission,
    # up to MISSIONS_MAX_WAYPOINTS waypoints.
    (r"^/api/v1/missions/", 16 * 1024 * 1024),
    # An organisation's envelope: a geofence of a few thousand vertices.
    (r"^/api/v1/organisations/[^/]+/envelope/", 2 * 1024 * 1024),
    (r"^/organisation/envelope/$", 2 * 1024 * 1024),
    # `/control` and a drone's commands: one command with its parameters.
    (r"^/control$", 64 * 1024),
    (r"^/api/v1/drones/[^/]+/commands/$", 64 * 1024),
]

# Password guessing: token requests per client address, failed logins per address and
# per username (accounts/throttling.py; the failures counted by config/throttling.py,
# which a drone's sign-in shares), like "10/min".
AUTH_TOKEN_RATE = env.str("AUTH_TOKEN_RATE", "10/min")
LOGIN_RATE = env.str("LOGIN_RATE", "10/min")
# Actions that move a drone, per user and, for API tokens, per token (config/throttling.py;
# 429 with Retry-After, docs/security.md "Rate limits"). Set well above what a person or
# a steering script sends, so only a runaway or stolen credential meets them: a click is
# one command and a script steering one drone by `navigate` needs about 10/s, so 30/s;
# starting a mission plans and sends every step, and a person starts one at a time, so
# 10/s; the past view's page sends teleoperation input at PASTVIEW_TELEOP_HZ (4/s), so 20/s.
COMMAND_RATE = env.str("COMMAND_RATE", "30/s")
MISSION_START_RATE = env.str("MISSION_START_RATE", "10/s")
TELEOP_RATE = env.str("TELEOP_RATE", "20/s")
