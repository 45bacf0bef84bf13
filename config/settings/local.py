"""Development settings: `make run` writes .data/run/env with the services' URLs."""

from config.env import BASE_DIR, env, read_data_env

read_data_env(BASE_DIR / ".data" / "run" / "env")

from .base import *  # noqa: E402,F403

# Error pages with tracebacks while developing; DEBUG=false previews production's.
DEBUG = env.bool("DEBUG", True)
# Mail is printed by `make run` instead of sent (invitations, password resets).
EMAIL_BACKEND = env.str("EMAIL_BACKEND", "django.core.mail.backends.console.EmailBackend")
