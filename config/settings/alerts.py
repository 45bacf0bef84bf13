"""Alerts: what a page shows on opening, and how e-mails and webhooks are delivered."""

from __future__ import annotations

from config.env import env

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
