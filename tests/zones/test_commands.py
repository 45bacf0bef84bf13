"""Published zones on a drone's commands: `POST /api/v1/drones/{id}/commands/` refuses a
move into a zone's volume (409 `zone`, naming the zone and its band) before anything is
sent; above the band, outside the zone's time window or with a valid authorisation, the
same move is sent."""

from __future__ import annotations

import json
from datetime import timedelta
from pathlib import Path

import pytest
from django.utils import timezone

from accounts.models import AuditEvent
from fleet.models import CommandLog, Drone
from onboard import envelope as env
from tests.fleet.conftest import client_for
from tests.fleet.test_envelope import HOME, command
from zones.models import Authorisation, Zone
from zones.store import import_bytes

pytestmark = pytest.mark.django_db(transaction=True)

FIXTURES = Path(__file__).parent / "fixtures"
# The field's centre: 150 m north of home (the zone spans 100–200 m north, ±50 m east).
INSIDE = env.ned_to_latlon(150.0, 0.0, HOME)


def field(organisation=None, **properties: object) -> Zone:  # type: ignore[no-untyped-def]
    document = json.loads((FIXTURES / "field.geojson").read_bytes())
    document["features"][0]["properties"].update(properties)
    import_bytes("field.geojson", json.dumps(document).encode(), organisation)
    return Zone.objects.get(identifier="LPT-FIELD-1")


def at_height(height: float) -> None:
    """ACME_1 hovering over home at `height` m, its last target there."""
    Drone.objects.filter(drone_id="ACME_1").update(alt=height, nav_target=[0.0, 0.0, -height])


def navigate_inside(user):  # type: ignore[no-untyped-def]
    return command(user, "navigate", lat=INSIDE[0], lon=INSIDE[1])


def assert_zone_refusal(response, responder, words: str = "inside") -> dict:  # type: ignore[no-untyped-def]
    assert response.status_code == 409, response.content
    body = response.json()
    assert body["code"] == "zone", body
    assert "'Test field' (LPT-FIELD-1" in body["error"] and words in body["error"], body
    assert responder.requests == []
    assert CommandLog.objects.filter(outcome="rejected").count() == 1
    return body


def test_a_leg_into_the_band_is_refused_and_one_over_it_is_sent(world_tx, flying):
    field()
    at_height(40.0)
    body = assert_zone_refusal(navigate_inside(world_tx.operator), flying)
    assert "0 m AGL – 60 m AGL (AGL taken as above home: terrain unknown)" in body["error"]
    CommandLog.objects.all().delete()
    beyond = env.ned_to_latlon(300.0, 0.0, HOME)
    response = command(world_tx.operator, "navigate", lat=beyond[0], lon=beyond[1])
    assert_zone_refusal(response, flying, "The straight leg to the target crosses")
    at_height(100.0)
    response = navigate_inside(world_tx.operator)
    assert response.status_code == 200, response.content
    response = command(world_tx.operator, "navigate", lat=beyond[0], lon=beyond[1])
    assert response.status_code == 200, response.content
    assert [r["command"] for r in flying.requests] == ["navigate", "navigate"]


def test_climbing_into_the_band_over_the_zone_is_refused(world_tx, flying):
    field()
    Drone.objects.filter(drone_id="ACME_1").update(nav_target=[150.0, 0.0, -100.0], alt=100.0)
    assert_zone_refusal(command(world_tx.operator, "altitude", value=-70), flying, "inside")


def test_taking_off_inside_a_zone_is_refused(world_tx, flying):
    field()
    Drone.objects.filter(drone_id="ACME_1").update(
        airborne=False, lat=INSIDE[0], lon=INSIDE[1], alt=0.0, nav_target=None, home=None
    )
    assert_zone_refusal(command(world_tx.operator, "takeoff", altitude=10), flying, "inside")


def test_a_drone_in_a_zone_may_fly_out_of_it(world_tx, flying):
    field()
    Drone.objects.filter(drone_id="ACME_1").update(nav_target=[150.0, 0.0, -40.0])
    assert command(world_tx.operator, "changeN", value=-150).status_code == 200


def test_outside_its_time_window_the_zone_does_not_apply(world_tx, flying):
    now = timezone.now()
    field(
        startDateTime=(now + timedelta(hours=1)).isoformat(),
        endDateTime=(now + timedelta(hours=2)).isoformat(),
    )
    at_height(40.0)
    assert navigate_inside(world_tx.operator).status_code == 200
    Zone.objects.update(
        applicability=[
            {"start": (now - timedelta(minutes=1)).isoformat(), "end": None, "schedule": []}
        ]
    )
    flying.requests.clear()
    assert_zone_refusal(navigate_inside(world_tx.operator), flying)


def test_another_organisations_zone_does_not_apply(world_tx, flying):
    field(world_tx.other_org)
    at_height(40.0)
    assert navigate_inside(world_tx.operator).status_code == 200


def test_a_conditional_zone_is_shown_not_enforced(world_tx, flying):
    field(restriction="CONDITIONAL")
    at_height(40.0)
    assert navigate_inside(world_tx.operator).status_code == 200


def authorise(user, zone: Zone, expires_at):  # type: ignore[no-untyped-def]
    return client_for(user).post(
        f"/api/v1/zones/{zone.pk}/authorisations/",
        {"issued_by": "Aveiro tower", "reference": "AUTH-2026-17", "expires_at": expires_at},
        content_type="application/json",
    )


def test_an_authorisation_opens_the_zone_until_it_expires(world_tx, flying):
    zone = field(world_tx.org, restriction="REQ_AUTHORISATION")
    at_height(40.0)
    body = assert_zone_refusal(navigate_inside(world_tx.operator), flying)
    assert "authorisation required" in body["error"]
    assert "No valid authorisation is recorded for it." in body["error"]

    expiry = (timezone.now() + timedelta(days=2)).isoformat()
    assert authorise(world_tx.operator, zone, expiry).status_code == 403
    assert authorise(world_tx.outsider, zone, expiry).status_code == 404
    response = authorise(world_tx.owner, zone, expiry)
    assert response.status_code == 201, response.content
    made = response.json()
    assert (made["organisation"], made["reference"], made["recorded_by"]) == (
        "acme",
        "AUTH-2026-17",
        "owner",
    )
    event = AuditEvent.objects.get(action="zone.authorisation")
    assert (event.organisation_id, event.actor_name) == (world_tx.org.pk, "owner")
    assert (
        event.detail["reference"] == "AUTH-2026-17" and event.detail["issued_by"] == "Aveiro tower"
    )

    assert navigate_inside(world_tx.operator).status_code == 200
    listed = client_for(world_tx.viewer).get(f"/api/v1/zones/{zone.pk}/authorisations/").json()
    assert [a["reference"] for a in listed["authorisations"]] == ["AUTH-2026-17"]

    Authorisation.objects.update(expires_at=timezone.now() - timedelta(seconds=1))
    flying.requests.clear()
    CommandLog.objects.all().delete()
    assert_zone_refusal(navigate_inside(world_tx.operator), flying)
    listed = client_for(world_tx.viewer).get(f"/api/v1/zones/{zone.pk}/authorisations/").json()
    assert listed["authorisations"][0]["expired"] is True


def test_an_authorisation_is_refused_for_a_prohibited_zone_or_in_the_past(world_tx):
    zone = field(world_tx.org)
    expiry = (timezone.now() + timedelta(days=1)).isoformat()
    assert authorise(world_tx.owner, zone, expiry).status_code == 409
    Zone.objects.update(restriction="authorisation_required")
    past = (timezone.now() - timedelta(days=1)).isoformat()
    response = authorise(world_tx.owner, zone, past)
    assert response.status_code == 400 and "expires_at" in response.json()["fields"]
    assert not Authorisation.objects.exists()


def test_a_leg_sent_while_still_climbing_crosses_a_band_it_would_pass_over_level(world_tx, flying):
    """A field from 20 m to 30 m. 5 m up over home and still climbing to 40 m, the drone
    is sent 300 m north: flown from 5 m on a slant it may be in the band over the field.
    Done climbing, the leg is level at 40 m, over the band, and is sent."""
    field(lowerLimit=20, upperLimit=30)
    beyond = env.ned_to_latlon(300.0, 0.0, HOME)
    Drone.objects.filter(drone_id="ACME_1").update(alt=5.0, nav_target=[0.0, 0.0, -40.0])
    response = command(world_tx.operator, "navigate", lat=beyond[0], lon=beyond[1])
    body = assert_zone_refusal(response, flying, "flown while the drone is still climbing")
    assert "from 5.0 m above home" in body["error"]
    at_height(40.0)
    response = command(world_tx.operator, "navigate", lat=beyond[0], lon=beyond[1])
    assert response.status_code == 200, response.content
    assert [r["command"] for r in flying.requests] == ["navigate"]
