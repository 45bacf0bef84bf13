"""Create the demo organisation and its admin user once; print how to log in."""

from __future__ import annotations

import secrets
from pathlib import Path

from django.apps import apps
from django.conf import settings
from django.contrib.auth import get_user_model
from django.core.management.base import BaseCommand
from django.db import transaction

from fleet.models import Membership, Organisation, Role


class Command(BaseCommand):
    help = "Create organisation 'demo' and user 'admin' (password generated on first run)."

    def add_arguments(self, parser):  # type: ignore[no-untyped-def]
        parser.add_argument("--url", default="http://127.0.0.1:8000/")

    @transaction.atomic
    def handle(self, *args, **options):  # type: ignore[no-untyped-def]
        password_file = Path(settings.DATA_DIR) / "admin_password"
        # The demo's simulated drones carry no Remote ID identity (docs/remote-id.md): the
        # demo organisation does not require one until its admin turns the rule on.
        organisation, _ = Organisation.objects.get_or_create(
            slug="demo", defaults={"name": "Demo", "require_remote_id": False}
        )
        # Nor does it need pre-flight checklists (docs/checklists.md) until its admin
        # turns the rule on; the checklists app builds on this one, so its model is named.
        apps.get_model("checklists", "Policy").objects.get_or_create(
            organisation=organisation,
            defaults={"required": False, "valid_minutes": settings.CHECKLIST_VALID_MINUTES_DEFAULT},
        )
        User = get_user_model()
        user = User.objects.filter(username="admin").first()
        if user is None or not password_file.exists():
            password = secrets.token_urlsafe(12)
            password_file.parent.mkdir(parents=True, exist_ok=True)
            password_file.write_text(password + "\n")
            password_file.chmod(0o600)
            if user is None:
                user = User.objects.create_superuser("admin", "", password)
            else:
                user.set_password(password)
                user.save()
        else:
            password = password_file.read_text().strip()
        Membership.objects.get_or_create(
            user=user, organisation=organisation, defaults={"role": Role.ADMIN}
        )
        self.stdout.write(
            f"Portal: {options['url']}  user: admin  password: {password}  "
            f"(kept in {password_file})"
        )
