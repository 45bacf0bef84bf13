"""`manage.py provision_drone <ID> [--org SLUG]`: a new broker password for a drone (PROTOCOL.md)."""

from __future__ import annotations

import json

from django.core.exceptions import ValidationError
from django.core.management.base import BaseCommand, CommandError

from fleet.credentials import ProvisioningError, provision


class Command(BaseCommand):
    help = "Create the drone if needed, issue new broker credentials, print them as JSON."

    def add_arguments(self, parser) -> None:  # type: ignore[no-untyped-def]
        parser.add_argument("drone_id")
        parser.add_argument("--org", dest="org", default=None, help="organisation slug")

    def handle(self, *args, **options) -> None:  # type: ignore[no-untyped-def]
        try:
            credentials = provision(options["drone_id"], options["org"])
        except ProvisioningError as exc:
            raise CommandError(str(exc)) from None
        except ValidationError as exc:
            raise CommandError("; ".join(exc.messages)) from None
        self.stdout.write(json.dumps(credentials.to_dict()))
