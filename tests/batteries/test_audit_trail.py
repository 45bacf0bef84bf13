"""Battery changes reach the audit trail: the retirement rules, a pack named or
re-rated, the pack chosen for a drone — who, what, old and new; a refused change
records nothing."""

from __future__ import annotations

import pytest
from django.test import Client
from rest_framework.test import APIClient

from accounts.models import AuditEvent

pytestmark = pytest.mark.django_db


def _api(user) -> APIClient:  # type: ignore[no-untyped-def]
    client = APIClient()
    client.force_authenticate(user)
    return client


def _entries(world, action: str) -> list[AuditEvent]:  # type: ignore[no-untyped-def]
    return list(AuditEvent.objects.filter(organisation=world.org, action=action).order_by("pk"))


def test_rule_changes_are_recorded_with_their_author_old_and_new(world):
    admin = _api(world.owner)
    url = f"/api/v1/organisations/{world.org.slug}/battery-policy/"
    before = admin.get(url).json()
    changed = admin.put(url, {"health_threshold": 0.6, "cycle_limit": 300}, format="json")
    assert changed.status_code == 200, changed.content
    (entry,) = _entries(world, "battery.rules")
    assert entry.actor == world.owner and entry.kind == AuditEvent.Kind.ORGANISATION
    assert entry.outcome == "ok" and entry.target == world.org.name
    assert entry.detail["changed"] == {
        "health_threshold": [before["health_threshold"], 0.6],
        "cycle_limit": [before["cycle_limit"], 300],
    }
    # Sending the same values again changes nothing and records nothing.
    assert admin.put(url, {"health_threshold": 0.6}, format="json").status_code == 200
    assert len(_entries(world, "battery.rules")) == 1


def test_refused_rule_changes_record_nothing(world):
    url = f"/api/v1/organisations/{world.org.slug}/battery-policy/"
    bad = _api(world.owner).put(url, {"health_threshold": 1.5}, format="json")
    assert bad.status_code == 400
    forbidden = _api(world.operator).put(url, {"health_threshold": 0.5}, format="json")
    assert forbidden.status_code == 403
    assert _entries(world, "battery.rules") == []


def test_a_pack_named_rerated_and_fitted_is_recorded(world):
    client = _api(world.operator)
    made = client.post(
        "/api/v1/batteries/", {"serial": "PACK-1", "rated_energy_wh": 50}, format="json"
    )
    assert made.status_code == 201, made.content
    pack = made.json()["id"]
    (added,) = _entries(world, "battery.add")
    assert added.actor == world.operator and added.target == "PACK-1"
    assert added.detail["changed"]["rated_energy_wh"] == [None, 50.0]

    rerated = client.patch(f"/api/v1/batteries/{pack}/", {"rated_energy_wh": 60}, format="json")
    assert rerated.status_code == 200, rerated.content
    (change,) = _entries(world, "battery.change")
    assert change.actor == world.operator and change.target == "PACK-1"
    assert change.detail["changed"] == {"rated_energy_wh": [50.0, 60.0]}

    url = f"/api/v1/drones/{world.drone.drone_id}/battery/"
    assert client.put(url, {"battery": pack}, format="json").status_code == 200
    assert client.put(url, {"battery": None}, format="json").status_code == 200
    fitted = _entries(world, "battery.fit")
    assert [e.detail["changed"]["battery"] for e in fitted] == [[None, "PACK-1"], ["PACK-1", None]]
    assert all(e.actor == world.operator and e.target == world.drone.drone_id for e in fitted)


def test_refused_pack_changes_record_nothing(world):
    client = _api(world.operator)
    pack = client.post("/api/v1/batteries/", {"serial": "PACK-2"}, format="json").json()["id"]
    start = AuditEvent.objects.filter(organisation=world.org).count()
    assert client.post("/api/v1/batteries/", {"serial": "PACK-2"}, format="json").status_code == 400
    bad_rating = client.patch(f"/api/v1/batteries/{pack}/", {"rated_energy_wh": -3}, format="json")
    assert bad_rating.status_code == 400
    url = f"/api/v1/drones/{world.drone.drone_id}/battery/"
    assert client.put(url, {"battery": 999999}, format="json").status_code == 400
    viewer = _api(world.viewer).put(url, {"battery": pack}, format="json")
    assert viewer.status_code == 403
    assert AuditEvent.objects.filter(organisation=world.org).count() == start


def test_the_pages_forms_record_their_author(world):
    operator, admin = Client(), Client()
    operator.force_login(world.operator)
    admin.force_login(world.owner)
    assert operator.post("/batteries/", {"serial": "PACK-F"}).status_code == 302
    pack = _api(world.operator).get("/api/v1/batteries/").json()["results"][0]["id"]
    chosen = operator.post(f"/batteries/drones/{world.drone.drone_id}/choose/", {"battery": pack})
    assert chosen.status_code == 302
    rules = admin.post("/batteries/rules/", {"health_threshold": "0.7", "cycle_limit": ""})
    assert rules.status_code == 302
    assert [e.actor for e in _entries(world, "battery.add")] == [world.operator]
    (fitted,) = _entries(world, "battery.fit")
    assert fitted.actor == world.operator and fitted.detail["changed"]["battery"] == [
        None,
        "PACK-F",
    ]
    (ruled,) = _entries(world, "battery.rules")
    assert ruled.actor == world.owner and ruled.detail["changed"]["health_threshold"][1] == 0.7
