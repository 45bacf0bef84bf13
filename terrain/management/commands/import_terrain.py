"""`manage.py import_terrain PATH`: import SRTM .hgt files or GeoTIFF DEMs (a file, a folder
or a ZIP of them) for the terrain clearance check."""

from __future__ import annotations

from pathlib import Path

from django.core.management.base import BaseCommand, CommandError

from terrain.formats import TerrainError
from terrain.importer import import_path


class Command(BaseCommand):
    help = "Import elevation data (SRTM .hgt, GeoTIFF in EPSG:4326; a file, folder or ZIP)."

    def add_arguments(self, parser) -> None:  # type: ignore[no-untyped-def]
        parser.add_argument("path", type=Path)

    def handle(self, *args, **options) -> None:  # type: ignore[no-untyped-def]
        try:
            imported = import_path(options["path"])
        except TerrainError as exc:
            raise CommandError(str(exc)) from exc
        for tile in imported.tiles:
            self.stdout.write(
                f"imported {tile.name}: {tile.cols} x {tile.rows} samples, "
                f"{tile.resolution_arcsec:g} arc-seconds, latitudes {tile.south:.5f}..{tile.north:.5f}, "
                f"longitudes {tile.west:.5f}..{tile.east:.5f}, {tile.void_count} voids"
            )
        for overlap in imported.overlaps:
            self.stdout.write(f"overlap: {overlap} (the newest import is used there)")
