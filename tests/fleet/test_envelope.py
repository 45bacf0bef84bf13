"""The flight envelope on the ground: its API, and commands refused before anything is sent."""

from __future__ import annotations

import json
import re

import pytest

from fleet import credentials, envelopes
from fleet.models import CommandLog, Drone, Organisation
from onboard import envelope as env
from runtime.processes import wait_for

from .conftest import Responder, client_for, mqtt_client, subscribe_acked

pytestmark = pytest.mark.django_db(transaction=True)

HOME = (40.6303, -8.6575)
URL = "/api/v1/organisations/acme/envelope/"


def square(half_m: float) -> list[list[float]]:
    corners = [(-half_m, -half_m), (-half_m, half_m), (half_m, half_m), (half_m, -half_m)]
    return [list(env.ned_to_latlon(n, e, HOME)) for n, e in corners]


def qgc_plan(fence_half_m: float) -> dict:
    """A geofence-only `.plan` as QGroundControl saves it."""
    return {
        "fileType": "Plan",
        "geoFence": {
            "circles": [],
            "polygons": [{"inclusion": True, "polygon": square(fence_half_m), "version": 1}],
            "version": 2,
        },
        "groundStation": "QGroundControl",
        "mission": {
            "cruiseSpeed": 15,
            "firmwareType": 12,
            "hoverSpeed": 5,
            "items": [],
            "plannedHomePosition": [*HOME, 0],
            "vehicleType": 2,
            "version": 2,
        },
        "rallyPoints": {"points": [], "version": 2},
        "version": 1,
    }


@pytest.fixture
def flying(world_tx, broker, gateway):  # type: ignore[no-untyped-def]
    """ACME_1 online and airborne at 10 m over home, last target there, answering commands."""
    creds = credentials.provision("ACME_1")
    Drone.objects.filter(drone_id="ACME_1").update(
        online=True,
        airborne=True,
        armed=True,
        lat=HOME[0],
        lon=HOME[1],
        alt=10.0,
        battery_remaining=0.9,
        home=list(HOME),
        nav_target=[0.0, 0.0, -10.0],
    )
    responder = Responder(f"mqtt://ACME_1:{creds.password}@127.0.0.1:{broker.port}", "ACME_1")
    yield responder
    responder.stop()


def command(user, command: str, **params: object):  # type: ignore[no-untyped-def]
    return client_for(user).post(
        "/api/v1/drones/ACME_1/commands/",
        {"command": command, "params": params},
        content_type="application/json",
    )


def assert_refused(response, limit_words: str, responder: Responder) -> None:  # type: ignore[no-untyped-def]
    assert response.status_code == 409, response.content
    body = response.json()
    assert body["code"] == "outside_envelope"
    assert limit_words in body["error"]
    assert responder.requests == []
    assert CommandLog.objects.filter(outcome="rejected").count() == 1


def test_the_defaults_are_shown_to_members(world_tx):
    response = client_for(world_tx.viewer).get(URL)
    assert response.status_code == 200
    body = response.json()
    assert (body["max_height"], body["max_distance"]) == (120.0, 1000.0)
    assert (body["min_move_height"], body["battery_reserve"]) == (2.0, 30.0)
    assert body["geoFence"] == {"version": 2, "polygons": [], "circles": []}
    assert client_for(world_tx.outsider).get(URL).status_code == 404


def test_only_admins_change_it(world_tx):
    response = client_for(world_tx.operator).put(
        URL, {"max_height": 50}, content_type="application/json"
    )
    assert response.status_code == 403
    response = client_for(world_tx.owner).put(
        URL, {"max_height": 50}, content_type="application/json"
    )
    assert response.status_code == 200, response.content
    assert Organisation.objects.get(slug="acme").envelope["max_height"] == 50.0


@pytest.mark.parametrize(
    ("body", "field"),
    [
        ({"max_height": -1}, "max_height"),
        ({"battery_reserve": 150}, "battery_reserve"),
        ({"geoFence": {"polygons": [{"polygon": [[40.6, -8.6], [40.7, -8.6]]}]}}, "polygon"),
        (
            {
                "geoFence": {
                    "polygons": [
                        {
                            "polygon": [
                                [40.62, -8.67],
                                [40.64, -8.64],
                                [40.64, -8.67],
                                [40.62, -8.64],
                            ]
                        }
                    ]
                }
            },
            "geoFence.polygons[0].polygon",
        ),
        (
            {
                "home": [40.70, -8.66],
                "geoFence": {"polygons": [{"inclusion": True, "polygon": square(100)}]},
            },
            "geoFence",
        ),
        ({**qgc_plan(100), "mission": {"plannedHomePosition": [40.70, -8.66, 0]}}, "geoFence"),
    ],
)
def test_a_malformed_envelope_is_refused_and_the_old_one_stays(world_tx, body, field):
    Organisation.objects.filter(slug="acme").update(envelope={"max_height": 80.0})
    response = client_for(world_tx.owner).put(URL, body, content_type="application/json")
    assert response.status_code == 400, response.content
    assert any(field in name for name in response.json()["fields"]), response.json()
    assert Organisation.objects.get(slug="acme").envelope == {"max_height": 80.0}


def test_a_qgc_geofence_imports_exports_and_is_enforced(world_tx, flying):
    plan = qgc_plan(200)
    response = client_for(world_tx.owner).put(URL, plan, content_type="application/json")
    assert response.status_code == 200, response.content
    exported = client_for(world_tx.viewer).get(URL + "plan/").json()
    assert exported["geoFence"] == plan["geoFence"]
    assert exported["mission"]["plannedHomePosition"][:2] == list(HOME)

    assert command(world_tx.operator, "changeE", value=150).status_code == 200
    flying.requests.clear()
    CommandLog.objects.all().delete()
    assert_refused(command(world_tx.operator, "changeE", value=250), "geofence", flying)


@pytest.mark.parametrize(
    ("name", "params", "words", "target"),
    [
        ("altitude", {"value": 115}, "maximum height of 120 m", None),
        ("changeN", {"value": 1200}, "maximum distance of 1000 m", None),
        ("changeN", {"value": 10}, "minimum height of 2 m", [0.0, 0.0, -1.0]),
        ("navigate", {"lat": 40.70, "lon": -8.6575}, "maximum distance", None),
        ("takeoff", {"altitude": 150}, "maximum height", None),
    ],
)
def test_commands_outside_the_envelope_are_refused_unsent(
    world_tx, flying, name, params, words, target
):
    if target is not None:
        Drone.objects.filter(drone_id="ACME_1").update(nav_target=target)
    assert_refused(command(world_tx.operator, name, **params), words, flying)


def test_relative_moves_add_to_the_current_target_not_the_position(world_tx, flying):
    drone = Drone.objects.get(drone_id="ACME_1")
    # What the agent answers to changeN 900 (the test responder only echoes).
    reply = {"ok": True, "result": {"target": {"north": 900.0, "east": 0.0, "down": -10.0}}}
    envelopes.remember_target(drone, "changeN", reply)
    assert Drone.objects.get(drone_id="ACME_1").nav_target == [900.0, 0.0, -10.0]
    # The drone still reports home, but its target is 900 m north: 200 more is too far.
    assert_refused(command(world_tx.operator, "changeN", value=200), "maximum distance", flying)


def test_under_the_battery_reserve_only_land_and_return_pass(world_tx, flying):
    Drone.objects.filter(drone_id="ACME_1").update(
        battery_remaining=0.2, nav_target=[80.0, 0.0, -10.0]
    )
    assert_refused(command(world_tx.operator, "changeE", value=10), "reserve of 30 %", flying)
    assert command(world_tx.operator, "changeN", value=-80).status_code == 200
    assert command(world_tx.operator, "land").status_code == 200


def test_control_answers_the_same_refusal(world_tx, flying):
    response = client_for(world_tx.operator).post(
        "/control", {"command": "altitude", "droneID": "ACME_1", "value": "500"}
    )
    assert response.status_code == 409
    assert response.json()["code"] == "outside_envelope"
    assert "maximum height" in response.json()["error"]
    assert flying.requests == []


def test_a_drone_override_lowers_but_never_raises(world_tx, flying):
    Drone.objects.filter(drone_id="ACME_1").update(max_height=30.0, max_distance=5000.0)
    assert_refused(
        command(world_tx.operator, "altitude", value=25), "maximum height of 30 m", flying
    )
    flying.requests.clear()
    CommandLog.objects.all().delete()
    assert_refused(command(world_tx.operator, "changeN", value=1500), "1000 m", flying)


def test_a_new_envelope_is_sent_to_the_drones(world_tx, broker, gateway):
    creds = credentials.provision("ACME_1")
    received: list[dict] = []
    client = mqtt_client(f"mqtt://ACME_1:{creds.password}@127.0.0.1:{broker.port}")

    def on_message(c, userdata, message):  # type: ignore[no-untyped-def]
        received.append(json.loads(message.payload))

    client.on_message = on_message
    subscribe_acked(client, "ACME_1/envelope/in")
    Drone.objects.filter(drone_id="ACME_1").update(max_distance=300.0)
    response = client_for(world_tx.owner).put(
        URL, {"max_height": 60}, content_type="application/json"
    )
    assert response.status_code == 200
    try:
        assert wait_for(lambda: received, timeout=10)
    finally:
        client.disconnect()
        client.loop_stop()
    sent = received[0]["envelope"]
    assert (sent["max_height"], sent["max_distance"]) == (60.0, 300.0)


def test_a_drone_back_online_gets_its_envelope_and_forgets_its_old_target(world_tx, fresh_redis):
    from fleet.signals import drones_came_online
    from workers import outbox

    Drone.objects.filter(drone_id="ACME_1").update(nav_target=[5.0, 0.0, -10.0])
    drones_came_online.send(sender=None, organisation_ids={world_tx.org.pk}, drone_ids=["ACME_1"])
    items = [json.loads(raw) for raw in fresh_redis.lrange(outbox.outbox_key(), 0, -1)]
    assert [item["topic"] for item in items] == ["ACME_1/envelope/in"]
    assert items[0]["payload"]["envelope"]["max_height"] == 120.0
    assert Drone.objects.get(drone_id="ACME_1").nav_target is None


def test_the_admin_form_refuses_a_malformed_envelope(world_tx):
    from fleet.admin import OrganisationForm

    organisation = Organisation.objects.get(slug="acme")
    fence = {"polygons": [{"polygon": [[40.6, -8.6], [40.7, -8.6]]}]}
    form = OrganisationForm(
        data={"name": "Acme", "slug": "acme", "envelope": json.dumps({"geoFence": fence})},
        instance=organisation,
    )
    assert not form.is_valid()
    assert "geoFence.polygons[0].polygon" in form.errors["envelope"][0]
    form = OrganisationForm(
        data={"name": "Acme", "slug": "acme", "envelope": json.dumps({"max_height": 90})},
        instance=organisation,
    )
    assert form.is_valid(), form.errors


@pytest.mark.parametrize(("who", "editable"), [("owner", True), ("viewer", False)])
def test_the_envelope_page_draws_the_fence_and_lets_admins_edit(world_tx, who, editable):
    from django.test import Client

    client = Client()
    client.force_login(getattr(world_tx, who))
    html = client.get("/organisation/envelope/").content.decode()
    assert 'id="envelope-map"' in html and "js/fleet_envelope.js" in html
    config = json.loads(
        re.search(r'<script id="envelope-config" type="application/json">(.*?)</script>', html)[1]
    )
    assert config["apiUrl"] == URL and config["editable"] is editable
    assert "Flight envelope" in client.get("/").content.decode()


def test_the_admin_lets_a_drone_lower_its_limits_only(world_tx):
    from fleet.admin import DroneForm

    drone = Drone.objects.get(drone_id="ACME_1")

    def form(**limits: float) -> DroneForm:  # type: ignore[no-untyped-def]
        data = {"organisation": world_tx.org.pk, "drone_id": "ACME_1", **limits}
        return DroneForm(data=data, instance=drone)

    assert form(max_height=50, max_distance=400).is_valid()
    raised = form(max_height=500)
    assert not raised.is_valid() and "120 m" in raised.errors["max_height"][0]
    assert not form(max_distance=0).is_valid()


def test_the_admin_pages_show_the_envelope_fields(world_tx):
    from django.contrib.auth import get_user_model
    from django.test import Client

    admin = get_user_model().objects.create_superuser("root", password="pw-for-the-admin")
    client = Client()
    client.force_login(admin)
    drone = Drone.objects.get(drone_id="ACME_1")
    page = client.get(f"/admin/fleet/drone/{drone.pk}/change/").content.decode()
    assert 'name="max_height"' in page and 'name="mqtt_password_hash"' not in page
    page = client.get(f"/admin/fleet/organisation/{world_tx.org.pk}/change/").content.decode()
    assert 'name="envelope"' in page
