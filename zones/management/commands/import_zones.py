"""`manage.py import_zones PATH [--org SLUG]`: import a GeoJSON, ED-269 or KML zone file."""

from __future__ import annotations

from pathlib import Path

from django.conf import settings
from django.core.management.base import BaseCommand, CommandError

from fleet.models import Organisation
from zones.formats.common import ZoneFileError
from zones.store import import_bytes


class Command(BaseCommand):
    help = (
        "Import published UAS geographical zones (GeoJSON, EUROCAE ED-269 JSON or KML); "
        "site-wide unless --org names an organisation."
    )

    def add_arguments(self, parser) -> None:  # type: ignore[no-untyped-def]
        parser.add_argument("path", type=Path)
        parser.add_argument("--org", default=None, help="the organisation's slug")
        parser.add_argument("--source", default="", help="the publisher (default: file name)")

    def handle(self, *args, **options) -> None:  # type: ignore[no-untyped-def]
        path: Path = options["path"]
        organisation = None
        if options["org"]:
            organisation = Organisation.objects.filter(slug=options["org"]).first()
            if organisation is None:
                raise CommandError(f"Unknown organisation {options['org']!r}.")
        if not path.is_file():
            raise CommandError(f"{path}: no such file")
        if path.stat().st_size > settings.ZONES_MAX_FILE_BYTES:
            raise CommandError(f"{path}: larger than {settings.ZONES_MAX_FILE_BYTES} bytes")
        try:
            done = import_bytes(path.name, path.read_bytes(), organisation, options["source"])
        except ZoneFileError as exc:
            raise CommandError(f"{path}: refused, nothing imported: {exc}") from exc
        scope = organisation.slug if organisation else "site-wide"
        self.stdout.write(
            f"imported {done.zones} zones ({done.file_format}, {scope}; "
            f"{done.updated} updated in place)"
        )
