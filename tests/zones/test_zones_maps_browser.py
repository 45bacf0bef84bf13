"""Published zones on the other maps, in a real browser: the fleet map around a drone and
a mission's page around its waypoints draw the zones in view (the site-wide field and the
organisation's heliport, never another organisation's reserve)."""

from __future__ import annotations

import pytest

from fleet.models import Drone
from missions.creation import create_mission
from onboard import envelope as env
from tests.conftest import login

from .test_zones_browser import HOME, zones_for

pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]


def zone_strokes(page, count: int = 2) -> list[str]:  # type: ignore[no-untyped-def]
    """The stroke colour of every zone drawn on the page's map, sorted, once `count` are
    drawn (a page that fits its map to its content reloads the zones for the new view)."""
    page.wait_for_function(
        f"document.querySelectorAll('.leaflet-skyhive-zones-pane path').length === {count}",
        timeout=10_000,
    )
    paths = page.locator(".leaflet-skyhive-zones-pane path")
    return sorted(paths.nth(i).get_attribute("stroke") for i in range(paths.count()))


def test_the_fleet_map_draws_the_zones_around_the_drones(page, live_asgi, world_tx):
    zones_for(world_tx)
    Drone.objects.filter(pk=world_tx.drone.pk).update(online=True, lat=HOME[0], lon=HOME[1])
    login(page, live_asgi, "operator")
    page.goto(f"{live_asgi.url}/")
    page.wait_for_selector("#fleet-map[data-zones='2']", timeout=10_000)
    # Authorisation required (the heliport), prohibited (the field).
    assert zone_strokes(page) == ["#b45309", "#b91c1c"]


def test_a_missions_page_draws_the_zones_around_its_waypoints(page, live_asgi, world_tx):
    zones_for(world_tx)
    near = env.ned_to_latlon(60.0, 0.0, HOME)
    mission = create_mission(
        organisation=world_tx.org,
        name="near the field",
        steps=[
            {"command": "arm"},
            {"command": "takeoff", "params": {"altitude": 100}},
            {"command": "navigate", "params": {"lat": near[0], "lon": near[1]}},
            {"command": "land"},
        ],
        home=HOME,
    )
    login(page, live_asgi, "operator")
    page.goto(f"{live_asgi.url}/missions/{mission.pk}/")
    # The page fits its map to the plan (one waypoint here) once the log is loaded.
    page.wait_for_selector(".leaflet-overlay-pane path[stroke='#999']", state="attached")
    view = page.evaluate(
        "() => { const m = window.skyhiveMission.map, c = m.getCenter();"
        " return {zoom: m.getZoom(), center: [c.lat, c.lng]}; }"
    )
    # Not the map's maximum zoom (a view some 50 m across): the zones around are in it.
    assert view["zoom"] <= 17, view
    assert view["center"] == pytest.approx(list(near), abs=1e-4)
    page.wait_for_selector("#mission-map[data-zones='2']", timeout=10_000)
    assert zone_strokes(page) == ["#b45309", "#b91c1c"]
