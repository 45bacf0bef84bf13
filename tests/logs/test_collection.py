"""Logs a drone uploads by itself (onboard.collect → /api/v1/logs/collect/), against the
real web app under uvicorn and a Celery worker: a link cut mid-upload resumes where the
ground is and the log is stored once; an operator's "off" sends nothing, "ground links
only" waits for Wi-Fi; another drone's password or a wrong one reaches nothing."""

from __future__ import annotations

import json
import time
from pathlib import Path

import pytest
import requests

from fleet.credentials import stored_hash
from fleet.models import Drone
from logs.models import CollectedLog, FlightLog
from logs.synth import synthetic_ulog
from onboard.collect import Collector, GroundClient, file_digest
from tests.logs.conftest import wait_until_processed
from tests.support.link_cut import LinkCut

pytestmark = [
    pytest.mark.e2e,
    pytest.mark.django_db(transaction=True),
    pytest.mark.usefixtures("logs_settings"),
]

PASSWORD = "drone-secret-1"
CHUNK = 16 * 1024
RATE = 50 * 1024 * 1024


@pytest.fixture
def drone(world_tx):  # type: ignore[no-untyped-def]
    return Drone.objects.create(
        organisation=world_tx.org, drone_id="ACME_COL1", mqtt_password_hash=stored_hash(PASSWORD)
    )


@pytest.fixture
def flight_file(tmp_path) -> Path:
    path = tmp_path / "ACME_COL1_flight.ulg"
    synthetic_ulog(path, seconds=8, rate_hz=100)
    return path


def _collector(folder: Path, url: str, gear: Path | None = None, uplink: str = "wifi"):  # type: ignore[no-untyped-def]
    client = GroundClient(url, "ACME_COL1", PASSWORD)
    return Collector(folder, client, gear_dir=gear, uplink=uplink, rate=RATE, chunk=CHUNK)


def test_a_link_cut_mid_upload_resumes_and_the_log_is_stored_once(
    drone, flight_file, tmp_path, live_logs, worker
):
    size = flight_file.stat().st_size
    assert size > 4 * CHUNK
    link = LinkCut("127.0.0.1", live_logs.port)
    try:
        collector = _collector(tmp_path / "queue", link.url)
        now = time.time()
        assert collector.add(flight_file, "fc", now - 60, now)
        link.cut_after(2 * CHUNK + CHUNK // 2)  # the third chunk is cut halfway
        assert collector.pass_once() is True  # still waiting: the link is down
        assert link.cuts == 1
        partial = CollectedLog.objects.get(drone=drone)
        assert partial.received == 2 * CHUNK and partial.log is None
        assert collector.pass_once() is True  # down still: nothing moves
        link.restore()
        assert collector.pass_once() is False
        # Queued again (an agent restarted before it forgot the manifest): answered "stored".
        assert collector.add(flight_file, "fc", now - 60, now)
        sent = collector.sent_bytes
        assert collector.pass_once() is False and collector.sent_bytes == sent
    finally:
        link.close()
    stored = CollectedLog.objects.get(drone=drone)
    assert (stored.received, stored.sha256) == (size, file_digest(flight_file))
    # Resumed at the ground's offset: the cut chunk again, never the whole file again.
    assert collector.sent_bytes == size
    log = FlightLog.objects.get(pk=stored.log_id)
    assert log.upload_path.read_bytes() == flight_file.read_bytes()
    assert (CollectedLog.objects.count(), FlightLog.objects.count()) == (1, 1)
    body = wait_until_processed(requests_session(live_logs.url, drone), str(log.pk))
    assert body["status"] == "ready", body


def requests_session(url: str, drone: Drone):  # type: ignore[no-untyped-def]
    """The log API as a person of the drone's organisation (the drone cannot read it)."""
    from rest_framework.authtoken.models import Token

    from fleet.models import Membership

    member = Membership.objects.filter(organisation=drone.organisation).first().user
    token, _ = Token.objects.get_or_create(user=member)
    session = requests.Session()
    session.headers["Authorization"] = f"Token {token.key}"

    class Client:
        def get(self, path: str):  # type: ignore[no-untyped-def]
            return session.get(url + path, timeout=10)

    return Client()


def test_collection_off_sends_nothing_and_ground_links_wait_for_wifi(
    drone, flight_file, tmp_path, live_logs
):
    gear = tmp_path / "gear"
    gear.mkdir()
    (gear / "collect.json").write_text(json.dumps({"collect": "off"}))
    collector = _collector(tmp_path / "queue", live_logs.url, gear, uplink="cellular")
    now = time.time()
    assert collector.add(flight_file, "onboard", now - 60, now) is False
    assert collector.pending() == [] and collector.pass_once() is False
    assert collector.sent_bytes == 0 and not CollectedLog.objects.exists()

    (gear / "collect.json").write_text(json.dumps({"collect": "ground_links"}))
    assert collector.add(flight_file, "onboard", now - 60, now) is True
    assert collector.pass_once() is True  # on a cellular uplink: waits
    assert collector.sent_bytes == 0 and not CollectedLog.objects.exists()

    (gear / "uplink.json").write_text(json.dumps({"type": "wifi"}))
    assert collector.pass_once() is False
    assert CollectedLog.objects.get(drone=drone).received == flight_file.stat().st_size


def test_only_the_drone_with_its_password_may_upload(drone, world_tx, live_logs):
    from rest_framework.authtoken.models import Token

    offer = {"kind": "fc", "name": "x.ulg", "size": 10, "sha256": "0" * 64,
             "flight_start": 1.0e9, "flight_end": 1.0e9 + 60}  # fmt: skip
    url = f"{live_logs.url}/api/v1/logs/collect/"
    wrong = requests.post(url, json=offer, auth=("ACME_COL1", "guess"), timeout=10)
    assert wrong.status_code == 401
    token, _ = Token.objects.get_or_create(user=world_tx.operator)
    person = requests.post(
        url, json=offer, headers={"Authorization": f"Token {token.key}"}, timeout=10
    )
    assert person.status_code in (401, 403)
    mine = requests.post(url, json=offer, auth=("ACME_COL1", PASSWORD), timeout=10)
    assert mine.status_code == 201, mine.text
    Drone.objects.create(
        organisation=world_tx.org, drone_id="ACME_COL2", mqtt_password_hash=stored_hash("other")
    )
    theirs = requests.put(
        f"{url}{mine.json()['id']}/?offset=0",
        data=b"x" * 10,
        headers={"Content-Type": "application/octet-stream"},
        auth=("ACME_COL2", "other"),
        timeout=10,
    )
    assert theirs.status_code == 404
    assert CollectedLog.objects.get().received == 0
    CollectedLog.objects.all().delete()
    Drone.objects.filter(pk=drone.pk).update(credentials_revoked=True)
    revoked = requests.post(url, json=offer, auth=("ACME_COL1", PASSWORD), timeout=10)
    assert revoked.status_code == 401
    assert not CollectedLog.objects.exists()
