"""The maintenance API: schedules that make no sense refused naming the field with nothing
changed, admins only for writes, other organisations 404, sign-offs by admins only, and a
log that cannot be changed and is in the audit trail."""

from __future__ import annotations

import pytest

from accounts.models import AuditEvent
from maintenance.models import Bulletin, LogEntry, Schedule
from tests import factories

from .support import api, flown

pytestmark = pytest.mark.django_db

URL = "/api/v1/organisations/acme/maintenance/schedules/"
GOOD = {"name": "Motor replacement", "drone": "ACME_1", "every_hours": 100}


@pytest.mark.parametrize(
    ("change", "field"),
    [
        ({"every_hours": -5}, "every_hours"),
        ({"every_hours": 0}, "every_hours"),
        ({"every_hours": None, "every_days": 0}, "every_days"),
        ({"every_hours": None, "every_flights": 2.5}, "every_flights"),
        ({"every_hours": None}, "every_hours"),  # no trigger at all
        ({"name": "  "}, "name"),
        ({"drone": None}, "drone"),  # no target
        ({"model": "X8"}, "model"),  # two targets
        ({"drone": "GLOBEX_1"}, "drone"),  # another organisation's drone
        ({"every_weeks": 3}, "every_weeks"),
    ],
)
def test_a_schedule_that_makes_no_sense_is_refused_naming_the_field(world, change, field):
    response = api(world.owner).post(URL, {**GOOD, **change}, format="json")
    assert response.status_code == 400, response.json()
    assert list(response.json()["fields"]) == [field]
    assert not Schedule.objects.exists()
    assert not AuditEvent.objects.filter(kind="maintenance").exists()


def test_admins_write_schedules_members_read_outsiders_see_nothing(world):
    assert api(world.operator).post(URL, GOOD, format="json").status_code == 403
    created = api(world.owner).post(URL, GOOD, format="json")
    assert created.status_code == 201
    pk = created.json()["id"]
    assert [s["name"] for s in api(world.viewer).get(URL).json()] == ["Motor replacement"]
    assert api(world.outsider).get(URL).status_code == 404
    assert api(world.outsider).get(f"/api/v1/maintenance/schedules/{pk}/").status_code == 404

    one = f"/api/v1/maintenance/schedules/{pk}/"
    assert api(world.owner).patch(one, {"every_hours": 0}, format="json").status_code == 400
    assert Schedule.objects.get().every_hours == 100
    changed = api(world.owner).patch(one, {"every_flights": 50}, format="json").json()
    assert (changed["every_hours"], changed["every_flights"]) == (100, 50)
    assert api(world.operator).delete(one).status_code == 403
    assert api(world.owner).delete(one).status_code == 204
    assert not Schedule.objects.exists()
    actions = AuditEvent.objects.filter(kind="maintenance").values_list("action", flat=True)
    assert sorted(actions) == [
        "maintenance.schedule_add",
        "maintenance.schedule_change",
        "maintenance.schedule_remove",
    ]


def _overdue_schedule(world) -> Schedule:  # type: ignore[no-untyped-def]
    flown(world.drone, minutes=20, count=3)
    return Schedule.objects.create(
        organisation=world.org, drone=world.drone, name="Propeller check", every_flights=3
    )


def test_only_admins_sign_off_and_the_log_never_changes(world):
    schedule = _overdue_schedule(world)
    log = "/api/v1/drones/ACME_1/maintenance/log/"
    body = {"schedule": schedule.pk, "notes": "props replaced", "parts": ["prop 10x4.5"]}
    refused = api(world.operator).post(log, body, format="json")
    assert refused.status_code == 403
    assert not LogEntry.objects.exists()
    assert api(world.owner).post(log, {**body, "notes": ""}, format="json").status_code == 400
    assert api(world.outsider).post(log, body, format="json").status_code == 404

    signed = api(world.owner).post(log, body, format="json")
    assert signed.status_code == 201
    entries = api(world.viewer).get(log).json()["results"]
    assert [(e["item"], e["signed_by"], e["parts"]) for e in entries] == [
        ("Propeller check", "owner", ["prop 10x4.5"])
    ]
    assert entries[0]["usage"] == [{"trigger": "flights", "used": 3, "limit": 3}]
    audit = AuditEvent.objects.get(action="maintenance.sign_off")
    assert audit.actor == world.owner and audit.detail["notes"] == "props replaced"

    entry = LogEntry.objects.get()
    entry.notes = "nothing done"
    with pytest.raises(PermissionError):
        entry.save()
    with pytest.raises(PermissionError):
        entry.delete()
    with pytest.raises(PermissionError):
        LogEntry.objects.filter(pk=entry.pk).update(notes="nothing done")
    with pytest.raises(PermissionError):
        LogEntry.objects.all().delete()
    assert LogEntry.objects.get().notes == "props replaced"


def test_a_bulletin_opens_an_item_on_every_drone_of_its_model_until_each_is_signed(world):
    factories.drone(world.org, "ACME_X8A", specs={"MODEL": "X8", "TYPE": "OCTOCOPTER"})
    factories.drone(world.org, "ACME_X8B", specs={"MODEL": "x8"})
    factories.drone(world.org, "ACME_HEX", specs={"MODEL": "H6"})
    url = "/api/v1/organisations/acme/maintenance/bulletins/"
    note = {"model": "X8", "title": "Arm clamp torque", "text": "Torque to 2 Nm."}
    assert api(world.operator).post(url, note, format="json").status_code == 403
    assert api(world.owner).post(url, {**note, "title": ""}, format="json").status_code == 400
    assert not Bulletin.objects.exists()
    bulletin = api(world.owner).post(url, note, format="json").json()

    due = api(world.viewer).get("/api/v1/organisations/acme/maintenance/due/").json()
    assert [d["drone"] for d in due] == ["ACME_X8A", "ACME_X8B"]
    verdict = api(world.viewer).get("/api/v1/drones/ACME_X8A/airworthiness/").json()
    assert verdict["airworthy"] is False
    assert "service bulletin 'Arm clamp torque' open since" in verdict["reasons"][0]

    log = "/api/v1/drones/ACME_X8A/maintenance/log/"
    body = {"bulletin": bulletin["id"], "notes": "torqued"}
    assert api(world.owner).post(log, body, format="json").status_code == 201
    assert api(world.owner).post(log, body, format="json").status_code == 409
    hex_log = "/api/v1/drones/ACME_HEX/maintenance/log/"
    assert api(world.owner).post(hex_log, body, format="json").status_code == 400
    due = api(world.viewer).get("/api/v1/organisations/acme/maintenance/due/").json()
    assert [d["drone"] for d in due] == ["ACME_X8B"]
    assert LogEntry.objects.count() == 1


def test_the_schema_documents_the_maintenance_api(world):
    paths = api(world.viewer).get("/api/schema/?format=json").json()["paths"]
    for path in (
        "/api/v1/organisations/{slug}/maintenance/schedules/",
        "/api/v1/maintenance/schedules/{id}/",
        "/api/v1/organisations/{slug}/maintenance/bulletins/",
        "/api/v1/organisations/{slug}/maintenance/due/",
        "/api/v1/drones/{drone_id}/maintenance/",
        "/api/v1/drones/{drone_id}/maintenance/log/",
    ):
        assert path in paths, path
    body = paths["/api/v1/drones/{drone_id}/maintenance/log/"]["post"]["requestBody"]
    assert body["content"]["application/json"]["schema"]["$ref"].endswith("/SignOffBodyRequest")
