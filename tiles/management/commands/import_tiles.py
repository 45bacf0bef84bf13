"""`manage.py import_tiles PATH`: import an MBTiles file, a z/x/y tile folder or a ZIP of one."""

from __future__ import annotations

from pathlib import Path

from django.core.management.base import BaseCommand, CommandError

from tiles.importer import import_path
from tiles.store import TileError


class Command(BaseCommand):
    help = "Import map tiles (MBTiles file, <z>/<x>/<y> folder or ZIP) for offline maps."

    def add_arguments(self, parser) -> None:  # type: ignore[no-untyped-def]
        parser.add_argument("path", type=Path)
        parser.add_argument("--name", default="", help="shown in the admin (default: metadata)")
        parser.add_argument("--attribution", default="", help="credit shown on the maps")
        parser.add_argument(
            "--scheme",
            choices=["xyz", "tms"],
            default="xyz",
            help="row order of a folder or ZIP (gdal2tiles writes tms unless --xyz)",
        )

    def handle(self, *args, **options) -> None:  # type: ignore[no-untyped-def]
        try:
            tileset = import_path(
                options["path"], options["name"], options["scheme"], options["attribution"]
            )
        except TileError as exc:
            raise CommandError(str(exc)) from exc
        self.stdout.write(
            f"imported {tileset.name}: {tileset.tile_count} tiles, zoom {tileset.min_zoom}"
            f"–{tileset.max_zoom}, bounds {tileset.west:.5f},{tileset.south:.5f},"
            f"{tileset.east:.5f},{tileset.north:.5f}"
        )
