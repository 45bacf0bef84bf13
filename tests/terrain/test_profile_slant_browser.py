"""The planner in a real browser draws a leg flown while climbing (a `navigate` straight
after its `takeoff`) on its slant: the height the drone has surely reached along it, the
lowest clearance on it in the profile's list, and the leg in red where the terrain check
refuses it; climbed first (`wait_for_flight`), the leg is drawn level."""

from __future__ import annotations

import json

import pytest

from onboard.envelope import ned_to_latlon
from terrain.models import TerrainClearance

from .dem import GROUND, HOME, hill_tile
from .test_climb_out import RIDGE_M, RIDGE_RISE, SLOPE
from .test_planner_browser import open_planner, terrain_on_the_server

pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]

CLIMB = 30.0
NORTH = ned_to_latlon(300.0, 0.0, HOME)


def ridge():  # type: ignore[no-untyped-def]
    """Flat ground, rising from 59.4 m north of home to a plateau 30 m above home at 152.2 m."""
    dem = hill_tile()
    dem.samples[:] = GROUND
    dem.samples[400:443, :] = GROUND + RIDGE_RISE
    return dem


def plan(page, *between: dict) -> None:  # type: ignore[no-untyped-def]
    """Take off to 30 m, `between`, fly 300 m north over the ridge and land, in the planner."""
    steps = [
        {"command": "arm", "params": {}},
        {"command": "takeoff", "params": {"altitude": CLIMB}},
        *between,
        {"command": "navigate", "params": {"lat": NORTH[0], "lon": NORTH[1]}},
        {"command": "land", "params": {}},
    ]
    page.wait_for_function("window.skyhivePlanner && window.skyhiveAirspace")
    page.evaluate(
        """(s) => {
          window.skyhivePlanner.steps.splice(0, window.skyhivePlanner.steps.length, ...s);
          document.dispatchEvent(new CustomEvent('skyhive:steps-changed'));
        }""",
        steps,
    )


def test_a_leg_flown_while_climbing_is_drawn_on_its_slant(page, live_asgi, world_tx, tmp_path):
    TerrainClearance.objects.create(organisation=world_tx.org, min_clearance=5.0)
    with terrain_on_the_server(tmp_path, ridge()):
        open_planner(page, live_asgi, world_tx)
        plan(page)
        slant = page.wait_for_selector("polyline.profile-slant", state="attached")
        assert slant.get_attribute("data-step") == "2"
        # The low edge: from the ground at home, 5 m (the minimum) 37.5 m out, the take-off's
        # 30 m at 225 m, level to the end; drawn with one corner for each.
        edge = json.loads(slant.get_attribute("data-edge"))
        expected = [[0.0, 0.0], [5.0 / SLOPE, 5.0], [CLIMB / SLOPE, CLIMB], [300.0, CLIMB]]
        assert edge == [[pytest.approx(d, abs=0.2), pytest.approx(h, abs=0.1)] for d, h in expected]  # fmt: skip
        assert len(slant.get_attribute("points").split()) == len(expected)
        # Surely only about 20 m up at the plateau's 30 m edge: below the ground, in red.
        assert "refused" in slant.get_attribute("class").split()
        assert page.locator("polygon.profile-slant-band.refused").count() == 1
        item = page.locator("#height-profile-slants li[data-step='2']")
        text = item.inner_text()
        assert text.startswith("Step 2 flown while climbing: as much as "), text
        below = float(text.split("as much as ")[1].split(" m")[0])
        assert (
            RIDGE_RISE - (RIDGE_M + 40.0) * SLOPE - 1 <= below <= RIDGE_RISE - RIDGE_M * SLOPE + 1
        )
        assert "refused: below the minimum of 5 m" in text
        assert "refused" in item.get_attribute("class").split()

        # Climbed first, the leg is level: nothing is drawn on a slant.
        plan(page, {"command": "wait_for_flight", "params": {}})
        page.wait_for_selector("polyline.profile-slant", state="detached")
        assert page.locator("#height-profile-slants").is_hidden()
        assert page.locator("polyline.profile-flight").count() == 1
