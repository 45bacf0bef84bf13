"""The fleet table API (search, filters, pages), the diffs the fleet socket sends, command
history pushed live, and specs shown with their units."""

from __future__ import annotations

import pytest
from django.test import Client
from django.utils import timezone

from fleet import listing
from fleet.consumers import changed_fields
from fleet.models import Drone

pytestmark = pytest.mark.django_db

# drone id → (online, armed, airborne, flight mode, battery, mission)
FLEET = {
    "GROUND_1": (True, False, False, "Stabilized1", 0.9, None),
    "ARMED_1": (True, True, False, "Stabilized1", 0.9, None),
    "AIR_1": (True, True, True, "PositionHold", 0.8, {"mission_id": "m1", "index": 3}),
    "HOME_1": (True, True, True, "RTL", 0.6, None),
    "LOW_1": (True, True, True, "PositionHold", 0.1, {"mission_id": "m1", "index": 7}),
    "LOST_1": (False, False, False, "", 0.7, None),
}


def make_fleet(org) -> None:  # type: ignore[no-untyped-def]
    now = timezone.now()
    for i, (drone_id, (online, armed, airborne, mode, battery, mission)) in enumerate(
        FLEET.items()
    ):
        Drone.objects.create(
            organisation=org,
            drone_id=drone_id,
            online=online,
            armed=armed,
            airborne=airborne,
            flight_mode=mode,
            battery_remaining=battery,
            battery_voltage=15.0,
            mission=mission,
            lat=40.0 + i * 0.001,
            lon=-8.0,
            alt=12.5 if airborne else 0.0,
            last_seen=now,
        )


def _table(client: Client, **params: str) -> dict:
    response = client.get("/fleet/table/", params)
    assert response.status_code == 200, response.content
    return response.json()


def test_the_table_api_filters_searches_and_states(world) -> None:
    make_fleet(world.org)
    client = Client()
    client.force_login(world.viewer)
    everything = _table(client)
    states = {d["drone_id"]: d["state"] for d in everything["results"]}
    assert states == {
        "ACME_1": "lost_link",
        "AIR_1": "airborne",
        "ARMED_1": "armed",
        "GROUND_1": "on_ground",
        "HOME_1": "returning",
        "LOST_1": "lost_link",
        "LOW_1": "low_battery",
    }
    assert everything["count"] == 7 and "GLOBEX_1" not in states

    def ids(**params: str) -> list[str]:
        return [d["drone_id"] for d in _table(client, **params)["results"]]

    assert ids(filter="airborne") == ["AIR_1", "HOME_1", "LOW_1"]
    assert ids(filter="low_battery") == ["LOW_1"]
    assert ids(filter="lost_link") == ["ACME_1", "LOST_1"]
    assert ids(filter="mission") == ["AIR_1", "LOW_1"]
    assert ids(filter="online,mission") == ["AIR_1", "LOW_1"]
    assert len(ids(filter="online")) == 5
    assert ids(q="air") == ["AIR_1"]
    assert ids(q="1", filter="airborne", page_size="2") == ["AIR_1", "HOME_1"]
    second = _table(client, q="1", filter="airborne", page_size="2", page="2")
    assert [d["drone_id"] for d in second["results"]] == ["LOW_1"]
    assert second["count"] == 3 and second["pages"] == 2


def test_the_map_columns_hold_every_placed_drone_in_the_table_s_state(world) -> None:
    make_fleet(world.org)
    Drone.objects.create(organisation=world.org, drone_id="NOWHERE_1", online=True)
    client = Client()
    client.force_login(world.viewer)
    table = {d["drone_id"]: d for d in _table(client)["results"]}
    markers = listing.marker_columns(world.org.pk)
    columns = markers["columns"]
    assert list(columns) == list(listing.MARKER_FIELDS)
    placed = {drone_id for drone_id, d in table.items() if d["position"]}
    assert "NOWHERE_1" not in placed and len(placed) == 6
    assert markers["count"] == len(columns["drone_id"]) and set(columns["drone_id"]) == placed
    for i, drone_id in enumerate(columns["drone_id"]):
        drone = table[drone_id]
        assert markers["states"][columns["state"][i]] == drone["state"]
        position = drone["position"]
        assert (columns["lat"][i], columns["lon"][i]) == (position["lat"], position["lon"])
        assert columns["alt"][i] == position["alt"]


@pytest.mark.parametrize(
    "params",
    [{"filter": "flying"}, {"page": "0"}, {"page": "x"}, {"page_size": "100000"}],
)
def test_the_table_api_refuses_what_it_does_not_know(world, params: dict) -> None:
    client = Client()
    client.force_login(world.viewer)
    response = client.get("/fleet/table/", params)
    assert response.status_code == 400 and response.json()["error"]


@pytest.mark.parametrize("page", ["5", "99999999999999999999999999"])
def test_a_page_past_the_last_is_empty(world, page: str) -> None:
    client = Client()
    client.force_login(world.viewer)
    table = _table(client, page=page, page_size="2")
    assert (table["count"], table["pages"], table["results"]) == (1, 1, [])
    assert table["page"] == int(page)


def test_the_table_api_is_for_members_only(world) -> None:
    assert Client().get("/fleet/table/").status_code == 302  # to the login page
    client = Client()
    client.force_login(world.outsider)
    assert [d["drone_id"] for d in _table(client)["results"]] == ["GLOBEX_1"]


def test_the_socket_sends_only_what_changed() -> None:
    before = {"drone_id": "A", "online": True, "position": {"lat": 1, "lon": 2, "alt": 3}}
    assert changed_fields(None, before) == before
    assert changed_fields(before, dict(before)) == {}
    after = {**before, "position": {"lat": 1, "lon": 2.5, "alt": 3}, "state": "airborne"}
    assert changed_fields(before, after) == {
        "drone_id": "A",
        "position": {"lat": 1, "lon": 2.5, "alt": 3},
        "state": "airborne",
    }


def test_the_drone_page_shows_state_and_battery_capacity_with_its_unit(world) -> None:
    world.drone.specs = {"BATTERY": {"CELL_COUNT": 4, "CAPACITY": 5500}, "FRAME_SIZE": "450"}
    world.drone.save()
    client = Client()
    client.force_login(world.viewer)
    html = client.get("/drones/ACME_1/").content.decode()
    assert "<dt>Capacity</dt><dd>5500 mAh</dd>" in html
    assert "<dt>Frame size</dt><dd>450 mm</dd>" in html
    assert "<dt>Cell count</dt><dd>4</dd>" in html
    assert 'class="state-badge state-lost_link">lost link<' in html
    assert 'id="command-history"' in html


def test_the_telemetry_overview_pages_and_filters_like_the_fleet_table(world) -> None:
    make_fleet(world.org)
    client = Client()
    client.force_login(world.viewer)
    html = client.get("/telemetry/", {"filter": "airborne"}).content.decode()
    assert 'data-drone="AIR_1"' in html and 'data-drone="LOW_1"' in html
    assert 'data-drone="GROUND_1"' not in html and "3 drones" in html
    html = client.get("/telemetry/", {"q": "low"}).content.decode()
    assert 'data-drone="LOW_1"' in html and "1 drone<" in html
    html = client.get("/telemetry/", {"page_size": "2", "page": "2"}).content.decode()
    assert html.count("<tr data-drone=") == 2 and "page 2 of 4" in html
    assert "page=1" in html and "page=3" in html and "page_size=2" in html
    # Unknown filters are ignored on the page (the API refuses them).
    assert client.get("/telemetry/", {"filter": "flying"}).status_code == 200


@pytest.mark.django_db(transaction=True)
async def test_the_fleet_socket_sends_each_drone_once_then_only_its_changes(world_tx) -> None:
    from channels.layers import get_channel_layer

    from tests.support.websocket import connect_websocket

    layer = get_channel_layer()
    group = world_tx.org.group_name
    fleet, connected, _ = await connect_websocket(
        f"/ws/fleet/?org={world_tx.org.slug}", world_tx.owner
    )
    one, one_connected, _ = await connect_websocket(
        f"/ws/fleet/?org={world_tx.org.slug}&drone=ACME_2", world_tx.owner
    )
    assert connected and one_connected
    try:
        snapshot = await fleet.receive_json_from(timeout=5)
        assert snapshot["type"] == "snapshot" and snapshot["drones"][0]["state"] == "lost_link"
        assert (await one.receive_json_from(timeout=5))["drones"] == []  # no such drone yet
        state = {"drone_id": "ACME_1", "online": True, "armed": False, "state": "on_ground"}
        for seen in ("12:00:00", "12:00:01"):
            payload = {"type": "drone", "drone": {**state, "last_seen": seen}}
            await layer.group_send(group, {"type": "fleet.event", "payload": payload})
        first = (await fleet.receive_json_from(timeout=5))["drone"]
        assert first["online"] is True and first["state"] == "on_ground"
        assert (await fleet.receive_json_from(timeout=5))["drone"] == {
            "drone_id": "ACME_1",
            "last_seen": "12:00:01",
        }
        # Nothing new, nothing sent; the one-drone socket hears nothing of ACME_1.
        payload = {"type": "drone", "drone": {**state, "last_seen": "12:00:01"}}
        await layer.group_send(group, {"type": "fleet.event", "payload": payload})
        command = {"type": "command", "drone_id": "ACME_2", "command": {"id": 1}}
        await layer.group_send(group, {"type": "fleet.event", "payload": command})
        assert await fleet.receive_nothing(timeout=0.5)
        assert (await one.receive_json_from(timeout=5)) == command
    finally:
        await fleet.disconnect()
        await one.disconnect()
