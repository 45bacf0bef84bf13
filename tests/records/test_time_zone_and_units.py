"""The operation's pages and exports in the portal's time zone (Django's TIME_ZONE, the one
every other page's dates follow) and its units (metres, seconds, watt-hours): a flight
armed at 03:30 UTC on 1 March is 22:30 on 28 February in New York, on the flight's page,
the logbook, its CSV and its PDF alike, and so are checklist runs and sign-offs."""

from __future__ import annotations

import csv
import io
import subprocess
from datetime import UTC, datetime, timedelta

import pytest
from django.test import Client

from checklists.models import Run
from maintenance.models import LogEntry
from records.models import FlightRecord, Origin

pytestmark = pytest.mark.django_db

ARMED = datetime(2026, 3, 1, 3, 30, tzinfo=UTC)
LOCAL = "2026-02-28 22:30:00"  # America/New_York, UTC-5 in winter


@pytest.fixture
def new_york(settings):  # type: ignore[no-untyped-def]
    settings.TIME_ZONE = "America/New_York"


def _record(world) -> FlightRecord:  # type: ignore[no-untyped-def]
    return FlightRecord.objects.create(
        organisation=world.org, drone=world.drone, drone_ident="ACME_1", origin=Origin.COMMAND,
        pilot=world.operator, pilot_name="operator", started_at=ARMED,
        ended_at=ARMED + timedelta(minutes=10), duration_s=600.0, distance_m=2500.0,
        max_height_m=30.0, max_distance_m=800.0, battery_start=0.9, battery_end=0.4,
        energy_wh=21.5, energy_method="voltage_current",
        track=[[0, 0, 0, 0], [300, 0.005, 0.0, 30.0], [600, 0, 0, 0]],
    )  # fmt: skip


def _viewer(world) -> Client:  # type: ignore[no-untyped-def]
    client = Client()
    client.force_login(world.viewer)
    return client


def test_the_logbook_page_csv_and_pdf_share_the_portals_time_zone(world, new_york, tmp_path):
    record = _record(world)
    client = _viewer(world)
    page = client.get("/records/drones/ACME_1/?period=month")
    html = page.content.decode()
    assert "Times in America/New_York" in html and LOCAL in html
    assert [t.period.strftime("%Y-%m") for t in page.context["totals"]] == ["2026-02"]
    # Metres on every distance, headers included (no column claims another unit).
    assert "(km)" not in html and "2500 m" in html
    flight = client.get(f"/records/flights/{record.pk}/").content.decode()
    assert "America/New_York" in flight and LOCAL in flight and "2500 m" in flight

    text = b"".join(client.get("/records/drones/ACME_1/?format=csv").streaming_content)
    row = next(csv.DictReader(io.StringIO(text.decode())))
    assert row["started_at"] == "2026-02-28T22:30:00-05:00"
    assert row["distance_m"] == "2500" and row["energy_wh"] == "21.5"

    pdf = tmp_path / "logbook.pdf"
    pdf.write_bytes(client.get("/records/drones/ACME_1/?format=pdf").content)
    shown = subprocess.run(
        ["pdftotext", "-layout", str(pdf), "-"], capture_output=True, text=True, check=True
    ).stdout
    assert f"ACME_1, {LOCAL} America/New_York" in shown
    assert "2500 m" in shown and "21.50 Wh" in shown


def test_checklist_runs_and_sign_offs_show_in_the_portals_time_zone(world, new_york):
    Run.objects.create(
        organisation=world.org, drone=world.drone, template_name="Before flight",
        results=[], passed=True, at=ARMED, expires_at=ARMED + timedelta(minutes=30),
    )  # fmt: skip
    LogEntry.objects.create(
        organisation=world.org, drone=world.drone, drone_ident="ACME_1",
        item_name="Motor check", signed_by_name="owner", signed_at=ARMED, notes="done",
    )  # fmt: skip
    client = _viewer(world)
    checklist = client.get("/checklists/drones/ACME_1/").content.decode()
    assert "America/New_York" in checklist and LOCAL in checklist
    maintenance = client.get("/maintenance/drones/ACME_1/").content.decode()
    assert "America/New_York" in maintenance and LOCAL in maintenance
