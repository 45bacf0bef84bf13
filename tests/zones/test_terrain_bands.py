"""An AMSL limit is placed with the home's elevation when terrain is imported, and widened
(to the ground, or without a top) when it is not."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from fleet.models import Organisation
from onboard import envelope as env
from terrain.importer import import_path
from tests.terrain.dem import GROUND, HOME, hill_tile, write_hgt
from zones.enforcement import move_violation
from zones.store import import_bytes

pytestmark = pytest.mark.django_db

FIXTURES = Path(__file__).parent / "fixtures"


def field_up_to(upper_amsl: float) -> None:
    """The test field (100–200 m north of home) from the ground to `upper_amsl` m AMSL."""
    document = json.loads((FIXTURES / "field.geojson").read_bytes())
    document["features"][0]["properties"].update(
        upperLimit=upper_amsl, upperVerticalReference="AMSL"
    )
    import_bytes("field.geojson", json.dumps(document).encode())


def refusal_at(height: float) -> str | None:
    """What refuses a leg at `height` m above home from home across the field."""
    organisation = Organisation.objects.get(slug="acme")
    move = env.Move("goto", (300.0, 0.0, -height), True)
    found = move_violation(organisation, HOME, move, (0.0, 0.0, -height), True)
    return None if found is None else found.message


def test_without_terrain_an_amsl_top_is_widened(world):
    field_up_to(50.0)
    message = refusal_at(100.0)
    assert message and "home elevation unknown: the band is widened" in message


def test_with_terrain_an_amsl_top_is_placed_above_the_home(world, settings, tmp_path):
    settings.TERRAIN_DIR = str(tmp_path / "terrain")
    import_path(write_hgt(tmp_path, hill_tile()))
    field_up_to(50.0)  # 40 m above a home on ground 10 m above sea level
    assert GROUND == 10.0
    message = refusal_at(35.0)
    assert message and "AMSL placed with home at 10 m AMSL" in message
    assert refusal_at(45.0) is None
