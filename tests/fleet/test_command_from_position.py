"""A command sent while the drone is still on its way to its last target is checked from
where the drone is as well: it turns to the new target at once, so round the inside
corner of an L-shaped inclusion fence the leg from its position leaves the fence where the
leg from its target does not. Refused unsent; accepted once the drone is there."""

from __future__ import annotations

import pytest

from fleet import envelopes
from fleet.models import Drone
from onboard.envelope import ned_to_latlon

from .test_envelope import HOME, assert_refused, command, flying  # noqa: F401 (fixture)

pytestmark = pytest.mark.django_db(transaction=True)

# A strip 40 m wide up the north axis to 120 m, and one 40 m wide east along 80–120 m
# north: 100 m north → 80 m east stays inside; home → there straight does not.
L_FENCE = [(-20, -20), (120, -20), (120, 100), (80, 100), (80, 20), (-20, 20)]


def at(north: float, east: float) -> dict:
    lat, lon = ned_to_latlon(north, east, HOME)
    return {"lat": lat, "lon": lon}


@pytest.fixture
def fenced_on_its_way(world_tx, flying):  # type: ignore[no-untyped-def]  # noqa: F811
    """ACME_1 over home, flying to its last target 100 m north, inside the L."""
    polygon = [list(ned_to_latlon(n, e, HOME)) for n, e in L_FENCE]
    fence = {"version": 2, "polygons": [{"inclusion": True, "polygon": polygon, "version": 1}]}
    envelopes.set_envelope(world_tx.org, {"home": list(HOME), "geoFence": fence})
    Drone.objects.filter(drone_id="ACME_1").update(nav_target=[100.0, 0.0, -10.0])
    return flying


def test_a_leg_from_where_the_drone_is_that_leaves_the_fence_is_refused(
    world_tx, fenced_on_its_way
):
    corner = at(100, 80)
    refused = command(world_tx.operator, "navigate", **corner)
    assert_refused(refused, "leaves the geofence", fenced_on_its_way)
    # There (within the agent's 2 m of its target), the same command goes.
    lat, lon = at(99, 0).values()
    Drone.objects.filter(drone_id="ACME_1").update(lat=lat, lon=lon)
    accepted = command(world_tx.operator, "navigate", **corner)
    assert accepted.status_code == 200, accepted.content
