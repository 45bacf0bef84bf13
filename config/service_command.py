"""The base of the ground's long-running `manage.py` services (gateway, ingest, past view,
media server)."""

from __future__ import annotations

from django.core.management.base import BaseCommand


class ServiceCommand(BaseCommand):
    """A service starts without Django's system checks. They run where a deployment
    changes: `migrate` (which `make run` calls at every start) and `makemigrations --check`
    in the suite. Repeated by every service and every Celery worker at each start, they
    import every URL conf, view and schema class: 0.4-0.7 s of CPU a process that serves
    none of them (config/celery.py skips them in workers the same way)."""

    requires_system_checks: list[str] = []
