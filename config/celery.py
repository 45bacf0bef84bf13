"""The Celery app: Redis broker, JSON only, late acks, time limits."""

import os

from celery import Celery

os.environ.setdefault("DJANGO_SETTINGS_MODULE", "config.settings.local")

app = Celery("skyhive")
app.config_from_object("django.conf:settings", namespace="CELERY")
app.autodiscover_tasks(["workers", "telemetry", "telemetry.logs", "missions"])
