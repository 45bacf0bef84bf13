"""A user of one organisation cannot see another's drones or missions: pages, API, websocket."""

import pytest
from channels.testing import WebsocketCommunicator
from rest_framework.test import APIClient

from missions.models import Mission
from tests.support.websocket import connect_websocket


@pytest.fixture
def missions(world):
    return (
        Mission.objects.create(organisation=world.org, name="Survey north field"),
        Mission.objects.create(organisation=world.other_org, name="Secret globex survey"),
    )


def api(user) -> APIClient:
    client = APIClient()
    client.force_authenticate(user)
    return client


def test_the_drone_page_of_another_organisation_is_not_found(client, world):
    client.force_login(world.owner)
    assert client.get("/drones/ACME_1/").status_code == 200
    assert client.get("/drones/GLOBEX_1/").status_code == 404


def test_the_drone_list_api_shows_only_the_users_organisation(world):
    body = api(world.viewer).get("/api/v1/drones/").json()
    assert [d["drone_id"] for d in body["results"]] == ["ACME_1"]


def test_another_organisations_drone_answers_404_in_the_api(world):
    response = api(world.owner).get("/api/v1/drones/GLOBEX_1/")
    assert response.status_code == 404
    assert response.json()["error"]


def test_missions_of_another_organisation_are_invisible(client, world, missions):
    mine, theirs = missions
    assert [m["name"] for m in api(world.owner).get("/api/v1/missions/").json()["results"]] == [
        "Survey north field"
    ]
    assert api(world.owner).get(f"/api/v1/missions/{theirs.pk}/").status_code == 404
    client.force_login(world.owner)
    assert client.get(f"/missions/{mine.pk}/").status_code == 200
    assert client.get(f"/missions/{theirs.pk}/").status_code == 404
    assert "Secret globex" not in client.get("/missions/").content.decode()


def test_a_user_without_organisation_sees_nothing(world):
    from tests.factories import person

    loner = person(None)
    assert api(loner).get("/api/v1/drones/").json()["results"] == []


def test_the_api_requires_authentication(world):
    response = APIClient().get("/api/v1/drones/")
    assert response.status_code in (401, 403)
    assert response.json()["error"]


@pytest.mark.django_db(transaction=True)
async def test_the_fleet_websocket_joins_only_the_users_organisation(world_tx):
    from channels.layers import get_channel_layer

    from config.asgi import application

    world = world_tx
    mine = await _connect(application, world.owner)
    theirs = await _connect(application, world.outsider)
    try:
        snapshot = await mine.receive_json_from(timeout=5)
        assert [d["drone_id"] for d in snapshot["drones"]] == ["ACME_1"]
        other_snapshot = await theirs.receive_json_from(timeout=5)
        assert [d["drone_id"] for d in other_snapshot["drones"]] == ["GLOBEX_1"]

        layer = get_channel_layer()
        await layer.group_send(
            world.org.group_name,
            {"type": "fleet.event", "payload": {"type": "drone", "drone_id": "ACME_1"}},
        )
        assert (await mine.receive_json_from(timeout=5))["drone_id"] == "ACME_1"
        assert await theirs.receive_nothing(timeout=0.5)
    finally:
        await mine.disconnect()
        await theirs.disconnect()


@pytest.mark.django_db(transaction=True)
async def test_the_fleet_websocket_refuses_anonymous_visitors():
    from config.asgi import application

    communicator = WebsocketCommunicator(
        application, "/ws/fleet/", headers=[(b"origin", b"http://127.0.0.1")]
    )
    connected, code = await communicator.connect()
    assert not connected
    await communicator.disconnect()


@pytest.mark.django_db(transaction=True)
async def test_the_fleet_websocket_refuses_an_organisation_the_user_is_not_in(world_tx):
    from config.asgi import application

    communicator = await _connect(application, world_tx.owner, query="?org=globex", expect=False)
    await communicator.disconnect()


async def _connect(application, user, query: str = "", expect: bool = True):
    communicator, connected, _ = await connect_websocket(f"/ws/fleet/{query}", user)
    assert connected is expect
    return communicator


# -- a token belongs to one organisation ---------------------------------------------------


@pytest.fixture
def member_of_both(world, missions):
    """The acme operator, also an admin of globex: a token of acme must still not reach
    globex, although its user may."""
    from fleet.models import Membership
    from logs.models import FlightLog

    Membership.objects.create(user=world.operator, organisation=world.other_org, role="admin")
    FlightLog.objects.create(organisation=world.other_org, owner=world.outsider, name="g.ulg")
    return world


def token_client(user, organisation) -> APIClient:  # type: ignore[no-untyped-def]
    from accounts import tokens

    client = APIClient()
    key = tokens.issue(user, name="script", organisation=organisation).key
    client.credentials(HTTP_AUTHORIZATION=f"Token {key}")
    return client


def test_a_token_of_one_organisation_gets_404_for_the_other_organisations_drone(
    member_of_both,
):
    world = member_of_both
    acme = token_client(world.operator, world.org)
    assert acme.get("/api/v1/drones/ACME_1/").status_code == 200
    assert acme.get("/api/v1/drones/GLOBEX_1/").status_code == 404
    assert acme.get("/api/v1/telemetry/drones/GLOBEX_1/latest/").status_code == 404
    refused = acme.post(
        "/api/v1/drones/GLOBEX_1/commands/", {"command": "arm", "params": {}}, format="json"
    )
    assert refused.status_code == 404
    assert not world.other_drone.commands.exists()
    # The same user's globex token reaches globex, and not acme.
    globex = token_client(world.operator, world.other_org)
    assert globex.get("/api/v1/drones/GLOBEX_1/").status_code == 200
    assert globex.get("/api/v1/drones/ACME_1/").status_code == 404


def test_a_token_of_one_organisation_lists_only_that_organisations_rows(member_of_both):
    world = member_of_both
    acme = token_client(world.operator, world.org)
    drones = acme.get("/api/v1/drones/").json()["results"]
    assert [d["drone_id"] for d in drones] == ["ACME_1"]
    missions = acme.get("/api/v1/missions/").json()["results"]
    assert [m["name"] for m in missions] == ["Survey north field"]
    logs = acme.get("/api/v1/logs/").json()
    assert "g.ulg" not in str(logs)
    theirs = Mission.objects.get(organisation=world.other_org)
    assert acme.get(f"/api/v1/missions/{theirs.pk}/").status_code == 404
    assert [m["organisation"] for m in acme.get("/api/v1/me/").json()["memberships"]] == ["acme"]
    assert acme.get("/api/v1/organisations/globex/envelope/").status_code == 404


def test_an_older_token_without_organisation_keeps_its_reach_and_is_flagged(member_of_both):
    from django.test import Client

    world = member_of_both
    unbound = token_client(world.operator, None)
    assert unbound.get("/api/v1/drones/GLOBEX_1/").status_code == 200
    assert unbound.get("/api/v1/drones/ACME_1/").status_code == 200
    page = Client()
    page.force_login(world.operator)
    assert "older: replace it" in page.get("/accounts/security/").content.decode()


def test_a_token_from_the_api_acts_for_the_organisation_it_names(member_of_both):
    body = {"username": "operator", "password": "correct horse battery staple"}
    unnamed = APIClient().post("/api/v1/token/", body, format="json")
    assert unnamed.status_code == 400 and "organisation" in unnamed.json()["fields"]
    named = APIClient().post("/api/v1/token/", {**body, "organisation": "globex"}, format="json")
    assert named.status_code == 200 and named.json()["organisation"] == "globex"
    client = APIClient()
    client.credentials(HTTP_AUTHORIZATION=f"Token {named.json()['token']}")
    assert client.get("/api/v1/drones/ACME_1/").status_code == 404
    assert client.get("/api/v1/drones/GLOBEX_1/").status_code == 200
