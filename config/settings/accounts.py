"""People: sign-in pages, the second factor, personal API tokens, invitations and mail."""

from __future__ import annotations

from config.env import env

LOGIN_URL = "login"
LOGIN_REDIRECT_URL = "fleet:index"
LOGOUT_REDIRECT_URL = "login"

# Asked by apps that do not import accounts (pastview's teleoperation) before a session
# moves a drone: (user, organisation, session) -> True while it owes the second factor.
SECOND_FACTOR_CHECK = "accounts.twofactor.owes_second_factor"
OTP_TOTP_ISSUER = "Skyhive"
# Sign-ins and failures are listed on each user's security page for this many days.
SIGN_IN_HISTORY_DAYS = env.int("SIGN_IN_HISTORY_DAYS", 90)
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
