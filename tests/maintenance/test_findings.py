"""Findings on one drone: opened once per source by the flight-log trends (the default
maintenance function) or by an admin through the API, they keep the drone on the ground
until signed off, like a bulletin for that drone alone."""

from __future__ import annotations

import pytest

from fleet import airworthiness
from logs.trends import open_maintenance
from maintenance.models import Bulletin

from .support import api

pytestmark = pytest.mark.django_db


def test_a_drifting_log_figure_opens_one_finding_that_grounds_the_drone(world):
    for _ in range(2):
        open_maintenance(world.drone, "ACME_1: vibration drifting", "x 41 m/s²", "log-trend:7:vx")
    finding = Bulletin.objects.get()
    assert (finding.drone, finding.model, finding.issued_by_name) == (world.drone, "", "platform")
    (reason,) = airworthiness.verdict(world.drone).reasons
    assert reason.startswith("maintenance due: finding 'ACME_1: vibration drifting' open since")

    log = "/api/v1/drones/ACME_1/maintenance/log/"
    body = {"bulletin": finding.pk, "notes": "motor 3 bearing replaced", "parts": ["bearing"]}
    assert api(world.owner).post(log, body, format="json").status_code == 201
    assert airworthiness.verdict(world.drone).airworthy


def test_an_admin_opens_a_finding_on_one_drone(world):
    url = "/api/v1/organisations/acme/maintenance/bulletins/"
    body = {"drone": "ACME_1", "title": "Cracked arm", "text": "Replace the front-left arm."}
    assert api(world.owner).post(url, {**body, "model": "X8"}, format="json").status_code == 400
    created = api(world.owner).post(url, body, format="json").json()
    assert (created["drone"], created["model"]) == ("ACME_1", "")
    items = api(world.viewer).get("/api/v1/drones/ACME_1/maintenance/").json()["items"]
    assert [(i["name"], i["kind"], i["status"]) for i in items] == [
        ("Cracked arm", "finding", "due")
    ]
