"""Settings shared by every environment; values come from the environment (config/env.py)."""

from __future__ import annotations

from django.core.exceptions import ImproperlyConfigured

from config.env import BASE_DIR, database_from_url, env

SECRET_KEY = env.str("SECRET_KEY", "insecure-development-key-change-me")
DEBUG = env.bool("DEBUG", False)
ALLOWED_HOSTS = env.list(
    "ALLOWED_HOSTS", cast=str.strip, default=["127.0.0.1", "localhost", "[::1]"]
)
CSRF_TRUSTED_ORIGINS = env.list("CSRF_TRUSTED_ORIGINS", cast=str.strip, default=[])

INSTALLED_APPS = [
    # django.contrib.admin behind the portal's sign-in and second factor (accounts/admin_site.py)
    "accounts.apps.AdminConfig",
    "django.contrib.auth",
    "django.contrib.contenttypes",
    "django.contrib.sessions",
    "django.contrib.messages",
    "django.contrib.staticfiles",
    "rest_framework",
    "rest_framework.authtoken",
    "drf_spectacular",
    "channels",
    "fleet",
    "missions",
    "telemetry",
    "logs",
    "workers",
]

MIDDLEWARE = [
    # Under ASGI each of Django's own runs as its event-loop variant (config/middleware.py).
    # First: a request that meets a database or Redis outage anywhere below answers 503.
    "config.outage.outage_middleware",
    "django.middleware.security.SecurityMiddleware",
    "config.csp.ContentSecurityPolicyMiddleware",
    "config.bodylimits.BodyLimitMiddleware",
    "config.staticfiles.StaticFilesMiddleware",
    "django.contrib.sessions.middleware.SessionMiddleware",
    "django.middleware.common.CommonMiddleware",
    "django.middleware.csrf.CsrfViewMiddleware",
    "django.contrib.auth.middleware.AuthenticationMiddleware",
    "django.contrib.messages.middleware.MessageMiddleware",
    "django.middleware.clickjacking.XFrameOptionsMiddleware",
]

ROOT_URLCONF = "config.urls"
ASGI_APPLICATION = "config.asgi.application"
WSGI_APPLICATION = None

TEMPLATES = [
    {
        "BACKEND": "django.template.backends.django.DjangoTemplates",
        "DIRS": [BASE_DIR / "templates"],
        "APP_DIRS": True,
        "OPTIONS": {
            "context_processors": [
                "django.template.context_processors.request",
                "django.contrib.auth.context_processors.auth",
                "django.contrib.messages.context_processors.messages",
                "fleet.tenancy.organisation_context",
            ],
        },
    },
]

DATABASES = {
    "default": database_from_url(
        env.str("DATABASE_URL", "postgresql://skyhive:skyhive@127.0.0.1:54330/skyhive")
    )
}
DEFAULT_AUTO_FIELD = "django.db.models.BigAutoField"

REDIS_URL = env.str("REDIS_URL", "redis://127.0.0.1:63790/0")
MQTT_URL = env.str("MQTT_URL", "mqtt://ground:ground@127.0.0.1:1883")
# The ground broker: "mosquitto" (one node, the default) or "rabbitmq" (MQTT plugin,
# clusterable; docs/scaling.md). With several nodes, MQTT_URLS lists every node's MQTT
# listener in the order clients try them; AMQP_URLS are the same nodes' AMQP listeners
# (the gateway and ingest consume from shared queues there, as RabbitMQ 3.10's MQTT
# plugin has no shared subscriptions); RABBITMQ_API_URLS their management APIs (per-drone
# users and permissions, queue depths on the status page).
MQTT_BROKER = env.str("MQTT_BROKER", "mosquitto")
if MQTT_BROKER not in ("mosquitto", "rabbitmq"):
    raise ImproperlyConfigured(f"MQTT_BROKER must be mosquitto or rabbitmq, not {MQTT_BROKER!r}")
MQTT_URLS = env.list("MQTT_URLS", cast=str.strip, default=[MQTT_URL])
AMQP_URLS = env.list("AMQP_URLS", cast=str.strip, default=[])
RABBITMQ_API_URLS = env.list("RABBITMQ_API_URLS", cast=str.strip, default=[])
# Where Mosquitto's password and ACL files live, and its pid file for the SIGHUP reload.
MOSQUITTO_DIR = env.str("MOSQUITTO_DIR", str(BASE_DIR / ".data" / "run" / "mosquitto"))
DATA_DIR = env.str("DATA_DIR", str(BASE_DIR / ".data" / "run"))

# /health runs its checks at most this often per web process (anyone may ask it).
HEALTH_CACHE_S = env.float("HEALTH_CACHE_S", 3.0)

CACHES = {
    "default": {
        "BACKEND": "django.core.cache.backends.redis.RedisCache",
        "LOCATION": REDIS_URL,
    }
}

CHANNEL_LAYERS = {
    "default": {
        "BACKEND": "channels_redis.core.RedisChannelLayer",
        "CONFIG": {"hosts": [REDIS_URL], "capacity": 1000, "expiry": 30},
    }
}

AUTH_PASSWORD_VALIDATORS = [
    {"NAME": "django.contrib.auth.password_validation.UserAttributeSimilarityValidator"},
    {"NAME": "django.contrib.auth.password_validation.MinimumLengthValidator"},
    {"NAME": "django.contrib.auth.password_validation.CommonPasswordValidator"},
    {"NAME": "django.contrib.auth.password_validation.NumericPasswordValidator"},
]
LOGIN_URL = "login"
LOGIN_REDIRECT_URL = "fleet:index"
LOGOUT_REDIRECT_URL = "login"

LANGUAGE_CODE = "en-gb"
TIME_ZONE = "UTC"
USE_I18N = True
USE_TZ = True

STATIC_URL = "/static/"
STATICFILES_DIRS = [BASE_DIR / "static"]
# Served from the apps' and project's static folders; production collects to STATIC_ROOT.
WHITENOISE_USE_FINDERS = True
MEDIA_ROOT = env.str("MEDIA_ROOT", str(BASE_DIR / ".data" / "run" / "media"))
MEDIA_URL = "/media/"

# Uploads are streamed to disk (never held in memory) beyond this size.
FILE_UPLOAD_MAX_MEMORY_SIZE = 2 * 1024 * 1024
# Form fields (not files) of one request: the largest non-file body any address takes
# (a mission of MISSIONS_MAX_WAYPOINTS steps), and no more fields or files than a form has.
DATA_UPLOAD_MAX_MEMORY_SIZE = 16 * 1024 * 1024
DATA_UPLOAD_MAX_NUMBER_FIELDS = 1000
DATA_UPLOAD_MAX_NUMBER_FILES = 10
LOG_UPLOAD_MAX_BYTES = env.int("LOG_UPLOAD_MAX_BYTES", 2 * 1024**3)
# Uploads one user may have under way at once at each upload address (config/uploadgate.py).
UPLOAD_MAX_CONCURRENT = env.int("UPLOAD_MAX_CONCURRENT", 2)
# Request bodies (config/bodylimits.py): HTTP 413 past these, before any view runs. The
# first matching pattern wins; None leaves the limit to the endpoint itself.
REQUEST_BODY_MAX_BYTES = env.int("REQUEST_BODY_MAX_BYTES", 1024 * 1024)
REQUEST_BODY_LIMITS = [
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

REST_FRAMEWORK = {
    "DEFAULT_AUTHENTICATION_CLASSES": [
        "rest_framework.authentication.SessionAuthentication",
        "rest_framework.authentication.TokenAuthentication",
    ],
    "DEFAULT_PERMISSION_CLASSES": ["rest_framework.permissions.IsAuthenticated"],
    "DEFAULT_PARSER_CLASSES": [
        "rest_framework.parsers.JSONParser",
        "rest_framework.parsers.FormParser",
        "rest_framework.parsers.MultiPartParser",
    ],
    "DEFAULT_SCHEMA_CLASS": "drf_spectacular.openapi.AutoSchema",
    "EXCEPTION_HANDLER": "config.api.exception_handler",
    "DEFAULT_PAGINATION_CLASS": "config.api.Pagination",
    "PAGE_SIZE": 100,
    "UNAUTHENTICATED_USER": "django.contrib.auth.models.AnonymousUser",
    # Proxies in front of the web processes whose X-Forwarded-For hop is trusted for the
    # client's address (throttling); 0 uses the connection's address.
    "NUM_PROXIES": env.int("NUM_PROXIES", 0),
}
# Password guessing: token requests per client address, failed logins per address and
# per username (config/throttling.py), like "10/min".
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

SPECTACULAR_SETTINGS = {
    "TITLE": "Skyhive API",
    "DESCRIPTION": "Plan, run and watch autonomous missions flown by one or many drones.",
    "VERSION": "1.0.0",
    "SERVE_INCLUDE_SCHEMA": False,
    "COMPONENT_SPLIT_REQUEST": True,
    "ENUM_NAME_OVERRIDES": {
        "MissionStatusEnum": "missions.models.MissionStatus",
        "StepStatusEnum": "missions.models.StepStatus",
        "AssignmentStatusEnum": "missions.models.Assignment.Status",
        "AssignmentReasonEnum": "missions.models.Assignment.Reason",
    },
}

CELERY_BROKER_URL = env.str("CELERY_BROKER_URL", REDIS_URL)
CELERY_RESULT_BACKEND = env.str("CELERY_RESULT_BACKEND", REDIS_URL)
CELERY_TASK_SERIALIZER = "json"
CELERY_RESULT_SERIALIZER = "json"
CELERY_ACCEPT_CONTENT = ["json"]
CELERY_TASK_ACKS_LATE = True
CELERY_TASK_REJECT_ON_WORKER_LOST = True
CELERY_WORKER_PREFETCH_MULTIPLIER = 1
CELERY_TASK_TIME_LIMIT = env.int("CELERY_TASK_TIME_LIMIT", 30 * 60)
CELERY_TASK_SOFT_TIME_LIMIT = env.int("CELERY_TASK_SOFT_TIME_LIMIT", 25 * 60)
# Reliability: a task is acknowledged only after it ran (acks late), and one
# whose worker process died is put back (reject on worker lost), so a worker killed
# mid-task loses nothing; every task is idempotent, so a rerun changes nothing twice.
# When the whole worker dies, Redis has no broker-side redelivery: the message waits in
# the unacknowledged set until it is older than the visibility timeout, then any worker
# puts it back (config/celery.py checks often). It must exceed the longest task
# (CELERY_TASK_TIME_LIMIT) or a slow task would run twice; tests set a short one.
CELERY_BROKER_TRANSPORT_OPTIONS = {
    "visibility_timeout": env.float("CELERY_VISIBILITY_TIMEOUT", 3600.0),
}
# Keep retrying the broker for ever (Celery stops after 100 attempts by default): a Redis
# restart must not end the worker.
CELERY_BROKER_CONNECTION_RETRY_ON_STARTUP = True
CELERY_BROKER_CONNECTION_MAX_RETRIES = None
# Replicated deployments (and test runs sharing one Redis) may name their own queue. Only
# when asked: a configured default queue can no longer be changed on `app.conf` at run
# time, which the end-to-end tests with an in-process gateway do.
if env.str("CELERY_TASK_DEFAULT_QUEUE", ""):
    CELERY_TASK_DEFAULT_QUEUE = env.str("CELERY_TASK_DEFAULT_QUEUE", "celery")
CELERY_RESULT_EXPIRES = 3600
CELERY_BEAT_SCHEDULE: dict = {}

# Drone link: heartbeats every 5 s; offline after 3 missed ones (docs/protocol.md).
HEARTBEAT_INTERVAL_S = env.float("HEARTBEAT_INTERVAL_S", 5.0)
OFFLINE_AFTER_MISSED_HEARTBEATS = env.int("OFFLINE_AFTER_MISSED_HEARTBEATS", 3)
COMMAND_TIMEOUT_S = env.float("COMMAND_TIMEOUT_S", 15.0)
# A command answered within this many seconds is logged once, with its answer; one still
# waiting then is logged as pending at that moment and completed when it ends.
COMMAND_LOG_PENDING_AFTER_S = env.float("COMMAND_LOG_PENDING_AFTER_S", 0.1)

LOGGING = {
    "version": 1,
    "disable_existing_loggers": False,
    "formatters": {"plain": {"format": "%(asctime)s %(levelname)s %(name)s: %(message)s"}},
    "handlers": {"console": {"class": "logging.StreamHandler", "formatter": "plain"}},
    "root": {"handlers": ["console"], "level": env.str("LOG_LEVEL", "INFO")},
    "loggers": {"django.db.backends": {"level": "WARNING"}},
}

# --- telemetry ---
# Raw samples are kept this many days, then only the 1-second and 1-minute aggregates.
TELEMETRY_RAW_RETENTION_DAYS = env.int("TELEMETRY_RAW_RETENTION_DAYS", 14)
TELEMETRY_1S_RETENTION_DAYS = env.int("TELEMETRY_1S_RETENTION_DAYS", 90)
TELEMETRY_1M_RETENTION_DAYS = env.int("TELEMETRY_1M_RETENTION_DAYS", 730)
# Daily partitions are created this many days ahead by the beat task.
TELEMETRY_PARTITIONS_AHEAD_DAYS = env.int("TELEMETRY_PARTITIONS_AHEAD_DAYS", 3)
# The ingest process flushes a COPY batch at this many rows or this often, whichever first.
TELEMETRY_FLUSH_ROWS = env.int("TELEMETRY_FLUSH_ROWS", 5000)
TELEMETRY_FLUSH_INTERVAL_S = env.float("TELEMETRY_FLUSH_INTERVAL_S", 0.2)
# Rows held in memory while the database is away; beyond this, messages are counted as overflow.
TELEMETRY_BUFFER_ROWS = env.int("TELEMETRY_BUFFER_ROWS", 500_000)
TELEMETRY_MAX_MESSAGE_BYTES = env.int("TELEMETRY_MAX_MESSAGE_BYTES", 256 * 1024)
# Accepted object timestamps relative to the ground's clock.
TELEMETRY_MAX_PAST_S = env.float("TELEMETRY_MAX_PAST_S", 7 * 86400)
TELEMETRY_MAX_FUTURE_S = env.float("TELEMETRY_MAX_FUTURE_S", 300)
# Live values pushed to dashboards at most this often per drone.
TELEMETRY_LIVE_HZ = env.float("TELEMETRY_LIVE_HZ", 5)
CELERY_BEAT_SCHEDULE["telemetry-maintain-partitions"] = {
    "task": "telemetry.maintain_partitions",
    "schedule": 3600.0,
}

# --- ground link ---
# Live fleet updates: at most one per drone per this many seconds (state changes always).
FLEET_PUSH_INTERVAL_S = env.float("FLEET_PUSH_INTERVAL_S", 1.0)
# The offline sweep (fleet.sweep_offline) runs this often under Celery beat.
OFFLINE_SWEEP_INTERVAL_S = env.float("OFFLINE_SWEEP_INTERVAL_S", 2.0)
CELERY_BEAT_SCHEDULE["fleet.sweep_offline"] = {
    "task": "fleet.sweep_offline",
    "schedule": OFFLINE_SWEEP_INTERVAL_S,
    "options": {"expires": OFFLINE_SWEEP_INTERVAL_S},
}
# The status page's counters (workers/counters.py): a process whose heartbeat is older
# than INSTANCE_TTL_S is gone (several missed flushes, so one slow Redis round trip does
# not flap it); refusals are kept per drone for at most REFUSAL_DRONES drone ids, later
# ones counted together, so a flood of invented ids cannot grow Redis.
INSTANCE_TTL_S = env.float("INSTANCE_TTL_S", 10.0)
REFUSAL_DRONES = env.int("REFUSAL_DRONES", 1000)
# Another tile server for every map (like one on the site's own network); empty (the
# default) uses the portal's own tiles (/tiles/, see "map tiles" below).
MAP_TILE_URL = env.str("MAP_TILE_URL", "")
MAP_TILE_ATTRIBUTION = env.str("MAP_TILE_ATTRIBUTION", "")
# Broker users kept in Mosquitto's passwd file when it is regenerated from the drones.
MQTT_SERVICE_USERS = env.list("MQTT_SERVICE_USERS", cast=str.strip, default=["ground"])
# What provision_drone tells a drone to connect to (default: MQTT_URL's host and port).
MQTT_PUBLIC_HOST = env.str("MQTT_PUBLIC_HOST", "")
MQTT_PUBLIC_PORT = env.int("MQTT_PUBLIC_PORT", 0)
# Drones are told mqtts:// URLs: MQTT_PUBLIC_PORT is then Mosquitto's TLS listener
# (MQTT_TLS_PORT of scripts/services.sh).
MQTT_PUBLIC_TLS = env.bool("MQTT_PUBLIC_TLS", False)

# --- missions ---
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
# Paused missions (no drone to replace a failing one) look for a drone this often.
MISSIONS_RESUME_INTERVAL_S = env.float("MISSIONS_RESUME_INTERVAL_S", 5.0)
# The panic button's hover altitude: 10 m, as in the panic-button experiment of
# [Paula 2018], §5.1.
MISSIONS_PANIC_ALTITUDE = env.float("MISSIONS_PANIC_ALTITUDE", 10.0)
# A drone that goes offline mid-mission is replaced when still offline this long after.
MISSIONS_OFFLINE_GRACE_S = env.float("MISSIONS_OFFLINE_GRACE_S", 30.0)
CELERY_BEAT_SCHEDULE["missions.resume_paused"] = {
    "task": "missions.resume_paused",
    "schedule": MISSIONS_RESUME_INTERVAL_S,
    "options": {"expires": MISSIONS_RESUME_INTERVAL_S},
}
# A panic call's drone down to MISSIONS_BATTERY_RESERVE on station is relieved this often.
CELERY_BEAT_SCHEDULE["missions.relieve_panic_stations"] = {
    "task": "missions.relieve_panic_stations",
    "schedule": MISSIONS_RESUME_INTERVAL_S,
    "options": {"expires": MISSIONS_RESUME_INTERVAL_S},
}
# `/control`'s startchain / stopchain start and stop a tracked mission; the fleet app
# names them here because it must not import the missions app that builds on it.
MISSION_START_STOP_HANDLERS = {
    "startchain": "missions.startstop.start_from_control",
    "stopchain": "missions.startstop.stop_from_control",
}

# --- flight logs ---
# Uploaded logs and their columnar stores, one folder per organisation and log.
LOGS_DIR = env.str("LOGS_DIR", f"{DATA_DIR}/logs")
# The Celery queue the import task goes to, served by workers of its own (docs/scaling.md):
# a 30-minute import never delays the fleet's work. Empty: the default queue.
LOGS_IMPORT_QUEUE = env.str("LOGS_IMPORT_QUEUE", "logs")
# ZIP archives (DFI): total uncompressed size and per-member compression ratio (ZIP bombs).
LOGS_MAX_UNCOMPRESSED_BYTES = env.int("LOGS_MAX_UNCOMPRESSED_BYTES", 2 * 1024**3)
LOGS_MAX_COMPRESSION_RATIO = env.float("LOGS_MAX_COMPRESSION_RATIO", 200.0)
# The most points one series request may ask for with `points` (min/max buckets).
LOGS_MAX_PLOT_POINTS = env.int("LOGS_MAX_PLOT_POINTS", 20_000)
# The log status enum in the OpenAPI schema (other apps also have a "status").
SPECTACULAR_SETTINGS["ENUM_NAME_OVERRIDES"]["FlightLogStatusEnum"] = "logs.models.LogStatus"

# --- past view ---
INSTALLED_APPS += ["pastview"]  # app label "pastview"
# Relative poses reach the page at most this often per drone (new frames and tracking
# events are pushed at once); teleoperation moves are rate-limited and bounded per step.
PASTVIEW_PUSH_HZ = env.float("PASTVIEW_PUSH_HZ", 30.0)
PASTVIEW_TELEOP_HZ = env.float("PASTVIEW_TELEOP_HZ", 4.0)
PASTVIEW_TELEOP_STEP_M = env.float("PASTVIEW_TELEOP_STEP_M", 0.5)

# --- queues by urgency (config/queues.py routes; docs/scaling.md lists who serves them) ---
# Work that keeps drones safe (replacing a failing drone, bringing in helpers, handling a
# drone gone offline, relieving a panic station) has a queue and workers of its own, so
# it never waits behind a log import or any other slow task. Empty: the default queue.
SAFETY_TASK_QUEUE = env.str("SAFETY_TASK_QUEUE", "safety")
SAFETY_TASKS = [
    "missions.replace_drone",
    "missions.collaborate",
    "missions.replace_offline",
    "missions.resume_paused",
    "missions.relieve_panic_stations",
    "fleet.sweep_offline",
]
CELERY_TASK_ROUTES = ["config.queues.route_task"]
# Imports: a log whose import stopped its worker (a crash, the kernel's OOM killer) this
# many times is marked failed instead of being delivered again.
LOGS_IMPORT_REDELIVERY_LIMIT = env.int("LOGS_IMPORT_REDELIVERY_LIMIT", 3)
# A running import shows it is alive this often; one silent for LOGS_STUCK_AFTER_S, or
# queued LOGS_UNSTARTED_AFTER_S ago and never started (its message lost), is retried or
# failed by the sweep, which runs every LOGS_SWEEP_INTERVAL_S.
LOGS_HEARTBEAT_INTERVAL_S = env.float("LOGS_HEARTBEAT_INTERVAL_S", 10.0)
LOGS_STUCK_AFTER_S = env.float("LOGS_STUCK_AFTER_S", 300.0)
LOGS_UNSTARTED_AFTER_S = env.float("LOGS_UNSTARTED_AFTER_S", 3600.0)
LOGS_SWEEP_INTERVAL_S = env.float("LOGS_SWEEP_INTERVAL_S", 60.0)
CELERY_BEAT_SCHEDULE["logs.sweep_stuck"] = {
    "task": "logs.sweep_stuck",
    "schedule": LOGS_SWEEP_INTERVAL_S,
    "options": {"expires": LOGS_SWEEP_INTERVAL_S},
}
# What parses an uploaded file into its store (path, store directory, limits=, progress=).
LOGS_IMPORT_FUNCTION = env.str("LOGS_IMPORT_FUNCTION", "logs.store.import_to_store")
# --- accounts ---
INSTALLED_APPS += ["django_otp", "django_otp.plugins.otp_totp", "accounts"]
# The token class first: its refusals answer 401 with `WWW-Authenticate: Token`.
REST_FRAMEWORK["DEFAULT_AUTHENTICATION_CLASSES"] = [
    "accounts.authentication.TokenAuthentication",
    "accounts.authentication.SessionAuthentication",
]
# Asked by apps that do not import accounts (pastview's teleoperation) before a session
# moves a drone: (user, organisation, session) -> True while it owes the second factor.
SECOND_FACTOR_CHECK = "accounts.twofactor.owes_second_factor"
# Personal API tokens: their default and longest life. DRF's older unnamed tokens are
# accepted until API_TOKEN_DEFAULT_DAYS after they were made.
API_TOKEN_DEFAULT_DAYS = env.int("API_TOKEN_DEFAULT_DAYS", 90)
API_TOKEN_MAX_DAYS = env.int("API_TOKEN_MAX_DAYS", 365)
# Invitation links expire this many days after they are sent.
INVITATION_DAYS = env.int("INVITATION_DAYS", 7)
# Outgoing mail (invitations, password resets): any SMTP server, from the environment.
EMAIL_BACKEND = env.str("EMAIL_BACKEND", "django.core.mail.backends.smtp.EmailBackend")
EMAIL_HOST = env.str("EMAIL_HOST", "localhost")
EMAIL_PORT = env.int("EMAIL_PORT", 25)
EMAIL_HOST_USER = env.str("EMAIL_HOST_USER", "")
EMAIL_HOST_PASSWORD = env.str("EMAIL_HOST_PASSWORD", "")
EMAIL_USE_TLS = env.bool("EMAIL_USE_TLS", False)
EMAIL_USE_SSL = env.bool("EMAIL_USE_SSL", False)
DEFAULT_FROM_EMAIL = env.str("DEFAULT_FROM_EMAIL", "skyhive@localhost")
# The audit trail records the caller of the request being served (accounts/audit.py).
MIDDLEWARE += ["accounts.audit.AuditContextMiddleware"]
# Sign-in: the second factor's state on every page (a reminder to enrol when required).
TEMPLATES[0]["OPTIONS"]["context_processors"].append("accounts.twofactor.context")
OTP_TOTP_ISSUER = "Skyhive"
# Sign-ins and failures are listed on each user's security page for this many days.
SIGN_IN_HISTORY_DAYS = env.int("SIGN_IN_HISTORY_DAYS", 90)

# --- alerts ---
INSTALLED_APPS += ["alerts"]
# Alerts raised in the last ALERT_RECENT_S are shown to a page that opens afterwards.
ALERT_RECENT_S = env.int("ALERT_RECENT_S", 600)
# Each e-mail or webhook delivery is tried up to this many times, waiting
# ALERT_RETRY_BASE_S, then twice as long each time.
ALERT_MAX_ATTEMPTS = env.int("ALERT_MAX_ATTEMPTS", 6)
ALERT_RETRY_BASE_S = env.float("ALERT_RETRY_BASE_S", 30.0)
ALERT_WEBHOOK_TIMEOUT_S = env.float("ALERT_WEBHOOK_TIMEOUT_S", 10.0)
# Webhooks go to public addresses only; on, also to loopback and private networks (a
# receiver on the site's own network). Never link-local (config/outbound.py).
ALERT_WEBHOOK_ALLOW_PRIVATE = env.bool("ALERT_WEBHOOK_ALLOW_PRIVATE", False)

# --- map tiles (offline first) ---
INSTALLED_APPS += ["tiles", "drf_spectacular_sidecar"]
TEMPLATES[0]["OPTIONS"]["context_processors"].append("tiles.layer.map_layer_context")
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
# Swagger UI and Redoc from the installed sidecar package, never from a CDN.
SPECTACULAR_SETTINGS.update(
    {"SWAGGER_UI_DIST": "SIDECAR", "SWAGGER_UI_FAVICON_HREF": "SIDECAR", "REDOC_DIST": "SIDECAR"}
)
# Teleoperation from the past view only while the drone's camera frames and tracked poses
# are this fresh (the page offers it and the server accepts moves on the same rule).
PASTVIEW_TELEOP_FRESH_S = env.float("PASTVIEW_TELEOP_FRESH_S", 3.0)
# The admin's map-tile upload has its own limit (TILES_UPLOAD_MAX_BYTES, config/asgi.py).
REQUEST_BODY_LIMITS.insert(0, (r"^/admin/tiles/tileset/add/$", None))

# Commands from web processes go over each process's own broker connection (the ground's
# MQTT_URL account; workers.direct), falling back to the gateways' outbox when it is down
# or the broker has not acknowledged a command within COMMAND_DIRECT_PUBACK_S seconds.
COMMAND_DIRECT = env.bool("COMMAND_DIRECT", True)
COMMAND_DIRECT_PUBACK_S = env.float("COMMAND_DIRECT_PUBACK_S", 0.5)
