"""`manage.py provision_drone <ID>... [--org SLUG]`: new broker passwords (docs/protocol.md).

One id prints one JSON object, as docs/protocol.md's "Provisioning a drone" says; several ids
are provisioned in one broker update and print a JSON list of those objects. `--sync`
rebuilds the broker's drone users from the database instead (a replaced broker node or
cluster) and prints what it did. `--upgrade` brings drone users the broker keeps in an
earlier form to the current one (on RabbitMQ: users still holding a password of their own,
which the client-id check would not see) and prints their ids; it changes nothing when
none is left, and `make run` runs it at every start.
"""

from __future__ import annotations

import json

from django.core.exceptions import ValidationError
from django.core.management.base import BaseCommand, CommandError

from fleet.credentials import (
    BrokerUnavailable,
    ProvisioningError,
    provision_many,
    sync_broker,
    upgrade_broker,
)


class Command(BaseCommand):
    help = "Create drones if needed, issue new broker credentials, print them as JSON."

    def add_arguments(self, parser) -> None:  # type: ignore[no-untyped-def]
        parser.add_argument("drone_ids", nargs="*", metavar="drone_id")
        parser.add_argument("--org", dest="org", default=None, help="organisation slug")
        parser.add_argument(
            "--sync",
            action="store_true",
            help="rebuild the broker's drone users and permissions from the database",
        )
        parser.add_argument(
            "--upgrade",
            action="store_true",
            help="bring drone users kept in an earlier form to the current one",
        )

    def handle(self, *args, **options) -> None:  # type: ignore[no-untyped-def]
        ids = options["drone_ids"]
        if sum((options["sync"], options["upgrade"], bool(ids))) != 1:
            raise CommandError("Give drone ids, or --sync or --upgrade alone.")
        try:
            if options["upgrade"]:
                self.stdout.write(json.dumps({"upgraded": upgrade_broker()}))
                return
            if options["sync"]:
                self.stdout.write(json.dumps(sync_broker().to_dict()))
                return
            issued = [c.to_dict() for c in provision_many(ids, options["org"])]
        except ProvisioningError as exc:
            raise CommandError(str(exc)) from None
        except ValidationError as exc:
            raise CommandError("; ".join(exc.messages)) from None
        except BrokerUnavailable as exc:
            raise CommandError(str(exc)) from None
        self.stdout.write(json.dumps(issued[0] if len(issued) == 1 else issued))
