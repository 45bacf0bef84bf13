"""The fleet and drone pages render for members, with what the scripts need."""

from __future__ import annotations

import json
import re

import pytest
from django.test import Client

from onboard.protocol import CONTROL_COMMANDS

pytestmark = pytest.mark.django_db


def _config(html: str) -> dict:
    match = re.search(
        r'<script id="fleet-config" type="application/json">(.*?)</script>', html, re.S
    )
    assert match, "the page carries its configuration"
    return json.loads(match.group(1))


def test_the_fleet_page_shows_the_map_and_only_the_organisations_drones(world, settings):
    settings.MAP_TILE_URL = ""
    client = Client()
    client.force_login(world.viewer)
    html = client.get("/").content.decode()
    assert 'id="fleet-map"' in html and "vendor/leaflet/leaflet.js" in html
    config = _config(html)
    assert config["tileUrl"] == "" and config["socketPath"] == "/ws/fleet/?org=acme"
    assert "GLOBEX_1" not in html
    # The drones come from the organisation's table API, a page at a time.
    table = client.get(config["tableUrl"]).json()
    assert [d["drone_id"] for d in table["results"]] == ["ACME_1"]


def test_the_drone_page_offers_every_command_to_operators_only(world):
    client = Client()
    client.force_login(world.operator)
    html = client.get("/drones/ACME_1/").content.decode()
    for command in CONTROL_COMMANDS:  # every control command has a form
        assert f'data-command="{command}"' in html, command
    assert html.count("data-confirm=") == 2  # disarm and resetfc ask first
    assert _config(html)["commandUrl"] == "/api/v1/drones/ACME_1/commands/"

    viewer = Client()
    viewer.force_login(world.viewer)
    assert "data-command=" not in viewer.get("/drones/ACME_1/").content.decode()
    assert viewer.get("/drones/GLOBEX_1/").status_code == 404


def test_the_drone_page_lists_announced_specs_and_sensors_readably(client, world):
    world.drone.specs = {"TYPE": "HEXACOPTER", "BATTERY": {"CELL_COUNT": 4, "CAPACITY": 5500}}
    world.drone.sensors = {"GAS": {"CO2": "<b>Sensirion</b> SCD30"}}
    world.drone.save()
    client.force_login(world.viewer)
    page = client.get("/drones/ACME_1/").content.decode()
    assert "<dt>Cell count</dt><dd>4</dd>" in page
    assert "<dt>Type</dt><dd>HEXACOPTER</dd>" in page
    # Announced by the drone, so escaped like any other input.
    assert "&lt;b&gt;Sensirion&lt;/b&gt; SCD30" in page
