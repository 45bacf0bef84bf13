"""A drone's figures over its flights: a drone whose vibration rises is flagged (alert and
maintenance finding, once), a drone with steady vibration is not; the statistic itself; the
fleet and drone trend API; naming the drone that flew a log."""

from __future__ import annotations

import shutil
from datetime import UTC, datetime, timedelta
from pathlib import Path

import pytest
from django.test import Client

from logs.synth_faults import px4_ulog
from logs.trends import Point, drift, judge

pytestmark = [pytest.mark.usefixtures("logs_settings")]

DAY0 = datetime(2026, 5, 1, 9, 0, tzinfo=UTC)
STEADY = [2.0, 2.1, 1.9, 2.05, 1.95, 2.0]
RISING = [2.0, 2.05, 2.1, 2.1, 2.15, 3.2]
# The topics of a short flight's log that the trends read (a quicker import).
TOPICS = {"vehicle_status", "vehicle_imu_status", "battery_status", "cpuload"}


def client_for(user) -> Client:  # type: ignore[no-untyped-def]
    client = Client()
    client.force_login(user)
    return client


def imported(organisation, path: Path, *, drone=None, flown_at=None):  # type: ignore[no-untyped-def]
    """A log imported (and checked) by the import's own code, as the worker runs it."""
    from logs.models import FlightLog
    from logs.services import process_log

    log = FlightLog(organisation=organisation, name=path.name, size=path.stat().st_size)
    log.drone, log.flown_at = drone, flown_at
    log.upload_path.parent.mkdir(parents=True, exist_ok=True)
    shutil.copy(path, log.upload_path)
    log.save()
    assert process_log(str(log.pk)) == "ready"
    log.refresh_from_db()
    return log


def fly(world, drone, levels: list[float], tmp_path: Path) -> list:  # type: ignore[no-untyped-def]
    return [
        imported(
            world.org,
            px4_ulog(
                tmp_path / f"{drone.drone_id}-{i}.ulg", vibration=v, seconds=15.0, topics=TOPICS
            ),
            drone=drone,
            flown_at=DAY0 + timedelta(days=i),
        )
        for i, v in enumerate(levels)
    ]


def test_rising_vibration_is_flagged_once_and_steady_vibration_is_not(world_tx, tmp_path, settings):
    from alerts.models import Alert
    from maintenance.models import Bulletin
    from tests import factories

    settings.LOGS_TREND_MAINTENANCE = [world_tx.org.slug]
    steady = factories.drone(world_tx.org, "ACME_STEADY")
    fly(world_tx, steady, STEADY, tmp_path)
    fly(world_tx, world_tx.drone, RISING, tmp_path)

    alerts = Alert.objects.filter(organisation=world_tx.org, kind=Alert.Kind.LOG_TREND)
    assert [(a.drone_id, a.severity) for a in alerts] == [("ACME_1", "warning")], [
        (a.title, a.detail) for a in alerts
    ]
    assert "vibration drifting from its own history" in alerts[0].title
    # The organisation wants a maintenance item: one finding on the drifting drone.
    findings = Bulletin.objects.filter(organisation=world_tx.org, issued_by_name="platform")
    assert [(f.drone.drone_id, f.title) for f in findings] == [("ACME_1", alerts[0].title)]

    body = client_for(world_tx.viewer).get("/api/v1/logs/trends/?check=vibration").json()
    by_drone = {d["drone"]: d for d in body["drones"]}
    assert [p["value"] for p in by_drone["ACME_1"]["points"]] == pytest.approx(RISING, abs=0.5)
    (found,) = by_drone["ACME_1"]["drift"]
    assert found["basis"] == "own" and found["n"] == 5
    assert found["value"] > found["limit"] == pytest.approx(found["mean"] + 3 * found["std"])
    assert by_drone["ACME_STEADY"]["drift"] == []
    assert body["statistic"]["sigmas"] == 3.0

    # Judging again (the drone named once more) raises nothing new.
    log = world_tx.drone.flight_logs.order_by("-flown_at").first()
    again = client_for(world_tx.operator).post(
        f"/api/v1/logs/{log.pk}/drone/",
        {"drone": "ACME_1", "flown_at": log.flown_at.isoformat()},
        content_type="application/json",
    )
    assert again.status_code == 200 and again.json()["drifts"][0]["basis"] == "own"
    assert alerts.count() == 1 and findings.count() == 1

    drone = client_for(world_tx.viewer).get("/api/v1/logs/trends/drones/ACME_1/").json()
    assert drone["checks"]["vibration"]["drift"][0]["basis"] == "own"
    assert drone["checks"]["clipping"]["drift"] == []
    outsider = client_for(world_tx.outsider)
    assert outsider.get("/api/v1/logs/trends/drones/ACME_1/").status_code == 404
    assert outsider.get("/api/v1/logs/trends/?check=vibration").json()["drones"] == []


def test_the_statistic_on_the_worse_side_own_and_fleet():
    history = [2.0, 2.1, 1.9, 2.0, 2.0]
    assert drift(2.2, history, basis="own", sigmas=3, min_history=5) is None
    found = drift(2.5, history, basis="own", sigmas=3, min_history=5)
    assert found is not None and found.limit == pytest.approx(2.0 + 3 * 0.0707107, abs=1e-6)
    # Fewer flights than the minimum: not judged; a better figure is never a drift.
    assert drift(9.0, history[:4], basis="own", sigmas=3, min_history=5) is None
    assert drift(0.1, history, basis="own", sigmas=3, min_history=5) is None
    # A lowest cell voltage is worse when lower.
    volts = [3.7, 3.72, 3.69, 3.71, 3.7]
    assert drift(3.5, volts, basis="own", lower_worse=True, sigmas=3, min_history=5)
    at = DAY0
    points = [Point(str(i), at, v, "m/s^2", "pass") for i, v in enumerate([2.0] * 2 + [6.0])]
    fleet = ([2.0, 2.1, 1.9, 2.0, 2.05, 1.95], 3)
    (only,) = judge(points, "vibration", fleet)
    assert only.basis == "fleet" and only.n == 6
    assert judge(points, "vibration", (fleet[0], 1)) == []


def test_naming_the_drone_of_a_log_is_for_operators_of_its_organisation(world_tx, tmp_path):
    log = imported(world_tx.org, px4_ulog(tmp_path / "one.ulg", seconds=15.0))
    url = f"/api/v1/logs/{log.pk}/drone/"
    operator = client_for(world_tx.operator)
    mine = operator.post(url, {"drone": "ACME_1"}, content_type="application/json")
    assert mine.status_code == 200 and mine.json()["drone"] == "ACME_1"
    theirs = operator.post(url, {"drone": "GLOBEX_1"}, content_type="application/json")
    assert theirs.status_code == 400
    bad_time = operator.post(
        url, {"drone": "ACME_1", "flown_at": "yesterday"}, content_type="application/json"
    )
    assert bad_time.status_code == 400
    viewer = client_for(world_tx.viewer)
    assert viewer.post(url, {"drone": None}, content_type="application/json").status_code == 403
    outsider = client_for(world_tx.outsider)
    assert outsider.post(url, {"drone": None}, content_type="application/json").status_code == 404
    log.refresh_from_db()
    assert log.drone_id == world_tx.drone.pk
