"""The maintenance pages without a browser: what a non-admin sees and may do, and no inline
script or style for the Content-Security-Policy to refuse."""

from __future__ import annotations

import re

import pytest
from django.test import Client

from maintenance.models import Bulletin, LogEntry, Schedule

from .support import flown

pytestmark = pytest.mark.django_db


def test_an_operator_sees_the_task_but_cannot_sign_it_off(world):
    flown(world.drone, minutes=15, count=2)
    schedule = Schedule.objects.create(
        organisation=world.org, drone=world.drone, name="Frame inspection", every_flights=2
    )
    client = Client()
    client.force_login(world.operator)
    page = client.get("/maintenance/drones/ACME_1/").content.decode()
    assert "Frame inspection" in page and 'id="maintenance-sign-off"' not in page
    posted = client.post(
        "/maintenance/drones/ACME_1/", {"item": f"schedule:{schedule.pk}", "notes": "done"}
    )
    assert posted.status_code == 403
    assert not LogEntry.objects.exists()
    assert client.get("/maintenance/drones/GLOBEX_1/").status_code == 404


def test_the_pages_keep_no_inline_script_or_style(world):
    client = Client()
    client.force_login(world.owner)
    drone_page = client.get("/drones/ACME_1/").content.decode()
    assert 'href="/maintenance/drones/ACME_1/"' in drone_page
    Schedule.objects.create(organisation=world.org, model="X8", name="Yearly", every_days=365)
    for path in ("/maintenance/", "/maintenance/drones/ACME_1/"):
        page = client.get(path).content.decode()
        assert not re.search(r"\sstyle=|\son[a-z]+=", page), path
        assert not re.search(r"<script(?![^>]*\ssrc=)(?![^>]*type=\"application/json\")", page)


def test_the_admin_forms_add_schedules_and_bulletins_through_the_same_rules(world):
    client = Client()
    client.force_login(world.owner)
    bad = {"action": "schedule", "name": "Motors", "drone": "ACME_1", "every_hours": "-1"}
    refused = client.post("/maintenance/", bad)
    assert refused.status_code == 400
    assert "every_hours: must be greater than zero" in refused.content.decode()
    assert client.post("/maintenance/", {**bad, "every_hours": "x"}).status_code == 400
    assert not Schedule.objects.exists()
    assert client.post("/maintenance/", {**bad, "every_hours": "100"}).status_code == 302
    bulletin = {"action": "bulletin", "model": "X8", "title": "Arms", "text": "Torque them."}
    assert client.post("/maintenance/", bulletin).status_code == 302
    operator = Client()
    operator.force_login(world.operator)
    assert operator.post("/maintenance/", bulletin).status_code == 403
    assert 'id="maintenance-add-schedule"' not in operator.get("/maintenance/").content.decode()
    assert Schedule.objects.get().every_hours == 100
    assert Bulletin.objects.count() == 1
