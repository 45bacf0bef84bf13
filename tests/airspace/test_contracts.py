"""The refusals other tools rely on are in the API schema: the command, mission creation,
start and panic operations name the 409 codes `conflict`, `terrain_clearance` and `zone`
they answer with (the reservations listing's place in it: tests/airspace/test_separation.py)."""

from __future__ import annotations

import pytest
from rest_framework.test import APIClient

pytestmark = pytest.mark.django_db


def operation_text(schema: dict, path: str, method: str = "post") -> str:
    operation = schema["paths"][path][method]
    responses = " ".join(r.get("description", "") for r in operation["responses"].values())
    return " ".join((operation.get("description", ""), responses))


@pytest.fixture
def schema(world) -> dict:  # type: ignore[no-untyped-def]
    client = APIClient()
    client.force_authenticate(world.viewer)
    return client.get("/api/schema/", HTTP_ACCEPT="application/json").json()


@pytest.mark.parametrize(
    "path,codes",
    [
        ("/api/v1/drones/{drone_id}/commands/", ("conflict", "terrain_clearance", "zone")),
        ("/api/v1/missions/", ("outside_envelope", "terrain_clearance", "zone")),
        ("/api/v1/missions/{id}/start/", ("conflict", "terrain_clearance", "zone")),
        ("/api/v1/missions/panic/", ("conflict",)),
    ],
)
def test_the_schema_names_each_operations_409_codes(schema, path, codes):
    text = operation_text(schema, path)
    for code in codes:
        assert f"`{code}`" in text or f"code: {code}`" in text, (path, code, text)
