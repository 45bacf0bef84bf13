"""Terrain test helpers: grids stored in a folder of the test's own."""

from __future__ import annotations

from pathlib import Path

import pytest

from .dem import Dem, hill_tile


@pytest.fixture
def terrain_dir(settings, tmp_path: Path) -> Path:  # type: ignore[no-untyped-def]
    settings.TERRAIN_DIR = str(tmp_path / "terrain")
    return tmp_path / "terrain"


@pytest.fixture(scope="session")
def hill() -> Dem:
    return hill_tile()


def stored_files(terrain_dir: Path) -> list[str]:
    """Every file left under TERRAIN_DIR (grids and staging folders alike)."""
    if not terrain_dir.exists():
        return []
    return sorted(
        p.relative_to(terrain_dir).as_posix() for p in terrain_dir.rglob("*") if p.is_file()
    )
