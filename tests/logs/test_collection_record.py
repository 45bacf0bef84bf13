"""A flight's record lists the logs its drone uploaded for that flight — those whose
flight overlaps the record's, stored ones only, never another drone's or another
flight's — in the API and on the record's page; a person of another organisation sees
neither."""

from __future__ import annotations

import hashlib
from datetime import timedelta

import pytest
from django.test import Client
from rest_framework.test import APIClient

from fleet.models import Drone
from logs.models import CollectedLog, FlightLog
from tests.records.support import at, days_ago, fly

pytestmark = pytest.mark.django_db


def _collected(drone, start, end, name: str, *, stored: bool = True) -> CollectedLog:  # type: ignore[no-untyped-def]
    log = None
    if stored:
        log = FlightLog.objects.create(
            organisation=drone.organisation, name=name, status="ready", format="dfi"
        )
    return CollectedLog.objects.create(
        organisation=drone.organisation, drone=drone, kind="onboard", name=name, size=10,
        sha256=hashlib.sha256(name.encode()).hexdigest(), received=10 if stored else 3,
        flight_started_at=start, flight_ended_at=end, log=log,
    )  # fmt: skip


def test_a_record_lists_the_logs_of_its_flight_only(world, settings):
    settings.LOG_COLLECT_ATTACH_MARGIN_S = 10.0
    armed = days_ago(1)
    record, flown = fly(world.drone, armed)
    start, end = at(flown.armed), at(flown.disarmed)
    # The drone's clock 2 s behind the ground's: still this flight.
    _collected(world.drone, start - timedelta(seconds=2), end - timedelta(seconds=2), "ours.dfi")
    _collected(world.drone, start, end, "half.dfi", stored=False)
    _collected(world.drone, end + timedelta(minutes=5), end + timedelta(minutes=9), "next.dfi")
    other = Drone.objects.create(organisation=world.org, drone_id="ACME_OTHER")
    _collected(other, start, end, "theirs.dfi")

    api = APIClient()
    api.force_authenticate(world.viewer)
    listed = api.get(f"/api/v1/flights/{record.pk}/").json()["logs"]
    assert [(entry["name"], entry["kind"], entry["status"]) for entry in listed] == [
        ("ours.dfi", "onboard", "ready")
    ]
    assert listed[0]["checks"] == f"/api/v1/logs/{listed[0]['id']}/checks/"

    client = Client()
    client.force_login(world.viewer)
    page = client.get(f"/records/flights/{record.pk}/").content.decode()
    assert "ours.dfi" in page and f"/logs/{listed[0]['id']}/" in page
    assert not any(name in page for name in ("half.dfi", "next.dfi", "theirs.dfi"))


def test_another_organisation_sees_neither_the_record_nor_its_logs(world, settings):
    record, flown = fly(world.drone, days_ago(1))
    _collected(world.drone, at(flown.armed), at(flown.disarmed), "ours.dfi")
    api = APIClient()
    api.force_authenticate(world.outsider)
    assert api.get(f"/api/v1/flights/{record.pk}/").status_code == 404
    log_id = CollectedLog.objects.get().log_id
    assert api.get(f"/api/v1/logs/{log_id}/").status_code == 404
