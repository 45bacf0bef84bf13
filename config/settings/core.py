"""The framework itself: the one list of apps, the request pipeline, templates, the API's
defaults, the database, caches and logging. Every other settings module is one concern."""

from __future__ import annotations

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
    "pastview",
    "livevideo",
    "django_otp",
    "django_otp.plugins.otp_totp",
    "accounts",
    "alerts",
    "records",
    "tiles",
    "zones",
    "terrain",
    "airspace",
    "batteries",
    "maintenance",
    "checklists",
    # Swagger UI and Redoc from the installed package, never from a CDN.
    "drf_spectacular_sidecar",
]

MIDDLEWARE = [
    # Under ASGI each of Django's own runs as its event-loop variant (config/middleware.py).
    # First: a request that meets a database or Redis outage anywhere below answers 503.
    "config.outage.outage_middleware",
    "django.middleware.security.SecurityMiddleware",
    "config.csp.ContentSecurityPolicyMiddleware",
    # No view meets a NUL character in its address, query or form (config/urlchars.py).
    "config.urlchars.NulCharacterMiddleware",
    "config.bodylimits.BodyLimitMiddleware",
    "config.staticfiles.StaticFilesMiddleware",
    "django.contrib.sessions.middleware.SessionMiddleware",
    "django.middleware.common.CommonMiddleware",
    "django.middleware.csrf.CsrfViewMiddleware",
    "django.contrib.auth.middleware.AuthenticationMiddleware",
    "django.contrib.messages.middleware.MessageMiddleware",
    "django.middleware.clickjacking.XFrameOptionsMiddleware",
    # The audit trail records the caller of the request being served (accounts/audit.py).
    "accounts.audit.AuditContextMiddleware",
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
                # The second factor's state on every page (a reminder to enrol when required).
                "accounts.twofactor.context",
                "tiles.layer.map_layer_context",
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

DATA_DIR = env.str("DATA_DIR", str(BASE_DIR / ".data" / "run"))
REDIS_URL = env.str("REDIS_URL", "redis://127.0.0.1:63790/0")

CACHES = {
    "default": {
        "BACKEND": "django.core.cache.backends.redis.RedisCache",
        "LOCATION": REDIS_URL,
        # One pool of kept connections per process, not one per request (config/cache.py).
        "OPTIONS": {"pool_class": "config.cache.ProcessConnectionPool"},
    }
}

CHANNEL_LAYERS = {
    "default": {
        "BACKEND": "channels_redis.core.RedisChannelLayer",
        "CONFIG": {"hosts": [REDIS_URL], "capacity": 1000, "expiry": 30},
    }
}

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

REST_FRAMEWORK = {
    # The token class first: its refusals answer 401 with `WWW-Authenticate: Token`.
    "DEFAULT_AUTHENTICATION_CLASSES": [
        "accounts.authentication.TokenAuthentication",
        "accounts.authentication.SessionAuthentication",
    ],
    "DEFAULT_PERMISSION_CLASSES": ["rest_framework.permissions.IsAuthenticated"],
    # DRF's own, refusing a body that holds NUL (config/parsers.py).
    "DEFAULT_PARSER_CLASSES": [
        "config.parsers.JSONParser",
        "config.parsers.FormParser",
        "config.parsers.MultiPartParser",
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

SPECTACULAR_SETTINGS = {
    "TITLE": "Skyhive API",
    "DESCRIPTION": "Plan, run and watch autonomous missions flown by one or many drones.",
    "VERSION": "1.0.0",
    "SERVE_INCLUDE_SCHEMA": False,
    "COMPONENT_SPLIT_REQUEST": True,
    # Enums of the same name in several apps ("status") each get their own schema name.
    "ENUM_NAME_OVERRIDES": {
        "MissionStatusEnum": "missions.models.MissionStatus",
        "StepStatusEnum": "missions.models.StepStatus",
        "AssignmentStatusEnum": "missions.models.Assignment.Status",
        "AssignmentReasonEnum": "missions.models.Assignment.Reason",
        "FlightLogStatusEnum": "logs.models.LogStatus",
    },
    # Swagger UI and Redoc from the installed sidecar package, never from a CDN.
    "SWAGGER_UI_DIST": "SIDECAR",
    "SWAGGER_UI_FAVICON_HREF": "SIDECAR",
    "REDOC_DIST": "SIDECAR",
}

LOGGING = {
    "version": 1,
    "disable_existing_loggers": False,
    "formatters": {"plain": {"format": "%(asctime)s %(levelname)s %(name)s: %(message)s"}},
    "handlers": {"console": {"class": "logging.StreamHandler", "formatter": "plain"}},
    "root": {"handlers": ["console"], "level": env.str("LOG_LEVEL", "INFO")},
    "loggers": {"django.db.backends": {"level": "WARNING"}},
}
