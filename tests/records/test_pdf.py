"""The logbook's PDF: read back by poppler (pdfinfo, pdftotext, pdftoppm), an
independent reader of the format, not by our own code."""

from __future__ import annotations

import subprocess
from datetime import UTC, datetime, timedelta
from pathlib import Path

import numpy as np
import pytest
from django.test import Client
from PIL import Image

# poppler-utils is installed by `scripts/bootstrap.sh test`.
pytestmark = pytest.mark.django_db

TRACK = [[0, 0, 0, 0], [20, 100, 0, 20], [40, 100, 100, 20], [60, 0, 0, 0]]


def _record(world, day: int, name: str = "Survey (north) \\ field"):  # type: ignore[no-untyped-def]
    from records.models import FlightRecord, Origin

    started = datetime(2026, 3, day, 9, tzinfo=UTC)
    return FlightRecord.objects.create(
        organisation=world.org, drone=world.drone, drone_ident="ACME_1", origin=Origin.MISSION,
        pilot=world.operator, pilot_name="operator", mission_name=name, started_at=started,
        ended_at=started + timedelta(minutes=5), duration_s=300.0, distance_m=341.0,
        max_height_m=20.0, battery_start=0.9, battery_end=0.55, energy_wh=12.5,
        energy_method="voltage_current", track=TRACK,
    )  # fmt: skip


def _pdf(world, tmp_path: Path, url: str) -> Path:  # type: ignore[no-untyped-def]
    client = Client()
    client.force_login(world.viewer)
    response = client.get(url)
    assert response.status_code == 200 and response["Content-Type"] == "application/pdf"
    path = tmp_path / "logbook.pdf"
    path.write_bytes(response.content)
    return path


def _run(*argv: str) -> str:
    return subprocess.run(argv, capture_output=True, text=True, check=True).stdout


def test_a_page_per_flight_with_its_figures_and_track(world, tmp_path, settings):
    settings.TIME_ZONE = "UTC"
    records = [_record(world, day) for day in (1, 2, 3)]
    path = _pdf(world, tmp_path, "/records/drones/ACME_1/?format=pdf")
    info = _run("pdfinfo", str(path))
    assert "Pages:           3" in info and "Syntax Error" not in info
    first = _run("pdftotext", "-f", "1", "-l", "1", "-layout", str(path), "-")
    assert f"Flight {records[-1].pk}: ACME_1, 2026-03-03 09:00:00" in first
    for text in ("Survey (north) \\ field", "341 m", "20.0 m", "90 % -> 55 %", "12.50 Wh"):
        assert text in first, (text, first)
    _run("pdftoppm", "-r", "40", "-f", "1", "-l", "1", "-png", str(path), str(tmp_path / "p"))
    pixels = np.asarray(Image.open(next(tmp_path.glob("p*.png"))).convert("RGB")).astype(int)
    # The track is drawn in blue (0.08, 0.44, 0.94): some of its pixels are on the page.
    r, g, b = pixels[..., 0], pixels[..., 1], pixels[..., 2]
    assert int(((b > 180) & (r < 90) & (g < 160)).sum()) > 20


def test_limits_and_isolation(world, tmp_path, settings):
    settings.RECORDS_PDF_MAX_FLIGHTS = 2
    for day in (1, 2, 3):
        _record(world, day)
    path = _pdf(world, tmp_path, "/records/pilots/operator/?format=pdf")
    assert "Pages:           2" in _run("pdfinfo", str(path))
    other = Client()
    other.force_login(world.outsider)
    assert other.get("/records/drones/ACME_1/?format=pdf").status_code == 404
    empty = _pdf(world, tmp_path, "/records/drones/ACME_1/?format=pdf&since=2030-01-01")
    assert "Pages:           1" in _run("pdfinfo", str(empty))
