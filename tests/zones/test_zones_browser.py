"""Published zones on the maps, in a real browser: the envelope page and the planner draw
the zones near what they show, styled by restriction, each with a popup naming it and its
band."""

from __future__ import annotations

from pathlib import Path

import pytest

from fleet.models import Organisation
from tests.conftest import login
from zones.store import import_bytes

pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]

FIXTURES = Path(__file__).parent / "fixtures"
HOME = [40.6303, -8.6575]


def zones_for(world) -> None:  # type: ignore[no-untyped-def]
    import_bytes("field.geojson", (FIXTURES / "field.geojson").read_bytes())
    name = "portugal.ed269.json"
    import_bytes(name, (FIXTURES / name).read_bytes(), world.org)
    import_bytes("reserve.kml", (FIXTURES / "reserve.kml").read_bytes(), world.other_org)


def test_the_envelope_page_draws_the_zones_with_their_popups(page, live_asgi, world_tx):
    zones_for(world_tx)
    Organisation.objects.filter(pk=world_tx.org.pk).update(envelope={"home": HOME})
    login(page, live_asgi, "owner")
    page.goto(f"{live_asgi.url}/organisation/envelope/")
    # Near home: the site-wide field and acme's heliport circle, not globex's reserve.
    page.wait_for_selector("#envelope-map[data-zones='2']", timeout=10_000)
    paths = page.locator(".leaflet-skyhive-zones-pane path")
    assert paths.count() == 2
    strokes = sorted(paths.nth(i).get_attribute("stroke") for i in range(2))
    assert strokes == ["#b45309", "#b91c1c"]  # authorisation required, prohibited
    field = page.locator(".leaflet-skyhive-zones-pane path[stroke='#b91c1c']")
    field.click(force=True)
    popup = page.locator(".leaflet-popup-content")
    popup.wait_for()
    assert popup.locator(".zone-name").inner_text() == "Test field"
    assert popup.locator(".zone-restriction").inner_text() == "Prohibited"
    assert popup.locator(".zone-band").inner_text().startswith("0 m AGL – 60 m AGL")
    assert "site-wide" in popup.locator(".zone-source").inner_text()


def planner_at_home_with_zones(page, live_asgi, world) -> None:  # type: ignore[no-untyped-def]
    """The planner moved to home, once the two zones near it are drawn."""
    zones_for(world)
    login(page, live_asgi, "operator")
    page.goto(f"{live_asgi.url}/missions/plan/")
    page.wait_for_function("window.skyhivePlanner && window.skyhivePlanner.map")
    page.evaluate("(c) => window.skyhivePlanner.map.setView(c, 16, {animate: false})", HOME)
    page.wait_for_selector("#planner-map[data-zones='2']", timeout=10_000)


def test_the_planner_draws_the_zones_where_it_is_moved(page, live_asgi, world_tx):
    planner_at_home_with_zones(page, live_asgi, world_tx)
    text = page.evaluate(
        "() => { const out = []; window.skyhivePlanner.map.skyhiveZones.eachLayer((l) => {"
        " l.openPopup(); out.push(l.getPopup().getContent()); }); return out; }"
    )
    assert any("Hospital heliport" in t and "121.92 m AGL" in t for t in text), text
    assert not any("Bird reserve" in t for t in text)


def test_a_zones_popup_stays_open_when_the_map_moves_and_the_zones_are_drawn_again(
    page, live_asgi, world_tx
):
    # Opening a popup near the map's edge pans the map, and every move asks for the zones
    # of the area in view again: the redraw must not close what the operator opened.
    planner_at_home_with_zones(page, live_asgi, world_tx)
    drawn = int(page.get_attribute("#planner-map", "data-zones-drawn"))
    page.evaluate(
        "() => window.skyhivePlanner.map.skyhiveZones.eachLayer((l) => {"
        " if (l.getPopup().getContent().includes('Hospital heliport')) l.openPopup(); })"
    )
    name = page.locator(".leaflet-popup-content .zone-name")
    assert name.inner_text() == "Hospital heliport"
    page.evaluate("() => window.skyhivePlanner.map.panBy([40, 0], {animate: false})")
    page.wait_for_function(
        f"Number(document.querySelector('#planner-map').dataset.zonesDrawn) > {drawn}",
        timeout=10_000,
    )
    # Leaflet's own word: a closed popup's content fades out of the page for a while.
    opened = page.evaluate(
        "() => { let open = null; window.skyhivePlanner.map.skyhiveZones.eachLayer((l) => {"
        " if (l.isPopupOpen()) open = l.getPopup().getContent(); }); return open; }"
    )
    assert opened and "Hospital heliport" in opened
