"""Production settings: everything secret or host-specific must come from the environment.

The settings refuse to load while a secret is missing or still the development fallback,
naming every variable to set in one line.
"""

from urllib.parse import urlsplit

from django.core.exceptions import ImproperlyConfigured

from config.env import env

from .base import *  # noqa: F403

# The broker and database accounts the development settings fall back to; never valid
# in production.
FALLBACK_MQTT_ACCOUNT = ("ground", "ground")
FALLBACK_DATABASE_PASSWORD = "skyhive"


def missing_secrets() -> list[str]:
    """What the environment lacks for production: SECRET_KEY, the ground's own broker
    account in MQTT_URL, a Redis password in REDIS_URL, a database password that is not
    the development one in DATABASE_URL (none at all is fine: a local socket's peer
    authentication)."""
    missing = []
    # Empty also when unset or naming (with a leading `$`) a variable that is unset.
    if not env.str("SECRET_KEY", ""):
        missing.append("SECRET_KEY")
    mqtt = urlsplit(env.str("MQTT_URL", ""))
    if not (mqtt.username and mqtt.password) or (mqtt.username, mqtt.password) == (
        FALLBACK_MQTT_ACCOUNT
    ):
        missing.append("MQTT_URL (with the ground's own user and password, not ground:ground)")
    if not urlsplit(env.str("REDIS_URL", "")).password:
        missing.append("REDIS_URL (with its password)")
    database = urlsplit(env.str("DATABASE_URL", ""))
    if not database.scheme or database.password == FALLBACK_DATABASE_PASSWORD:
        missing.append("DATABASE_URL (with its own password, not the development skyhive)")
    return missing


def proxy_ssl_header() -> tuple[str, str] | None:
    """The header a TLS-terminating proxy sets, trusted only when the site says a proxy
    is there: SECURE_PROXY_SSL_HEADER (`X-Forwarded-Proto: https`), or NUM_PROXIES > 0
    (then X-Forwarded-Proto). Trusted with no proxy, any client could claim https."""
    named = env.str("SECURE_PROXY_SSL_HEADER", "")
    if named:
        header, _, value = named.partition(":")
        if not (header.strip() and value.strip()):
            raise ImproperlyConfigured("SECURE_PROXY_SSL_HEADER is `Header-Name: value`")
        return ("HTTP_" + header.strip().upper().replace("-", "_"), value.strip())
    if env.int("NUM_PROXIES", 0) > 0:
        return ("HTTP_X_FORWARDED_PROTO", "https")
    return None


_missing = missing_secrets()
if _missing:
    raise ImproperlyConfigured("production settings need " + ", ".join(_missing))

STATIC_ROOT = BASE_DIR / "staticfiles"  # noqa: F405 - `make collectstatic` fills it
WHITENOISE_USE_FINDERS = False

SECURE_PROXY_SSL_HEADER = proxy_ssl_header()
SECURE_SSL_REDIRECT = True
SESSION_COOKIE_SECURE = True
CSRF_COOKIE_SECURE = True
SECURE_HSTS_SECONDS = 31536000
SECURE_HSTS_INCLUDE_SUBDOMAINS = True
SECURE_HSTS_PRELOAD = True
SECURE_CONTENT_TYPE_NOSNIFF = True
STORAGES = {
    "default": {"BACKEND": "django.core.files.storage.FileSystemStorage"},
    "staticfiles": {"BACKEND": "whitenoise.storage.CompressedManifestStaticFilesStorage"},
}
