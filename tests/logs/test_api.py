"""The logs API end to end: uploads processed by a real Celery worker, read back by range."""

from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np
import pytest
from django.test import Client

from logs.synth import synthetic_dataflash, synthetic_ulog
from tests.logs.conftest import upload, wait_until_processed
from tests.logs.dfi_builder import DESCRIPTION, write_dfi
from tests.logs.test_mission_log import mission_log
from tests.logs.test_rosbag import write_bag
from tests.logs.test_tlog import write_tlog
from tests.support.paths import REAL_ULOGS

pytestmark = [pytest.mark.e2e, pytest.mark.usefixtures("logs_settings")]
REAL_LOGS = REAL_ULOGS


def client_for(user) -> Client:  # type: ignore[no-untyped-def]
    client = Client()
    client.force_login(user)
    return client


def make_log(kind: str, directory: Path) -> Path:
    path = directory / f"flight.{kind}"
    if kind == "ulg":
        synthetic_ulog(path, seconds=4)
    elif kind == "bin":
        synthetic_dataflash(path, seconds=4, rate_hz=50)
    elif kind == "tlog":
        write_tlog(path, n=40)
    elif kind == "bag":
        write_bag(path, n=40)
    elif kind == "dfi":
        write_dfi(path)
    else:
        path.write_text(mission_log())
    return path


def processed(client: Client, path: Path) -> dict:
    response = upload(client, path)
    assert response.status_code == 201, response.content
    created = response.json()
    assert created["status"] == "processing"
    return wait_until_processed(client, created["id"])


@pytest.mark.parametrize(
    ("kind", "fmt"),
    [
        ("ulg", "ulog"),
        ("bin", "dataflash"),
        ("tlog", "tlog"),
        ("bag", "rosbag"),
        ("dfi", "dfi"),
        ("json", "mission"),
    ],
)
def test_every_format_uploads_and_becomes_ready_with_its_series(
    world_tx, worker, tmp_path, kind, fmt
):
    body = processed(client_for(world_tx.operator), make_log(kind, tmp_path))
    assert body["status"] == "ready", body
    assert body["error"] == ""
    assert body["format"] == fmt
    assert body["series"], body
    for series in body["series"]:
        assert set(series) >= {"path", "unit", "count", "start", "end"}
        assert series["count"] >= 1 and series["start"] <= series["end"]
    assert body["layers"] and body["owner"] == "operator"


def test_series_come_whole_without_points_and_min_max_downsampled_with_them(
    world_tx, worker, tmp_path
):
    client = client_for(world_tx.operator)
    body = processed(client, make_log("ulg", tmp_path))
    series = next(s for s in body["series"] if s["path"].startswith("sensor_combined/"))
    url = f"/api/v1/logs/{body['id']}/series/"

    whole = client.get(url, {"path": series["path"]}).json()
    assert len(whole["t"]) == len(whole["v"]) == series["count"] == 1000
    assert whole["t"] == sorted(whole["t"])

    few = client.get(url, {"path": series["path"], "points": 50}).json()
    assert 50 <= len(few["t"]) <= 100
    assert max(few["v"]) == max(whole["v"]) and min(few["v"]) == min(whole["v"])

    start, end = whole["t"][100], whole["t"][199]
    window = client.get(url, {"path": series["path"], "start": start, "end": end}).json()
    assert window["t"] == whole["t"][100:200] and window["v"] == whole["v"][100:200]


def test_series_requests_with_bad_parameters_get_the_error_shape(world_tx, worker, tmp_path):
    client = client_for(world_tx.operator)
    body = processed(client, make_log("dfi", tmp_path))
    url = f"/api/v1/logs/{body['id']}/series/"
    missing = client.get(url)
    assert missing.status_code == 400 and "path" in missing.json()["fields"]
    unknown = client.get(url, {"path": "nope/nothing"})
    assert unknown.status_code == 404
    assert unknown.json()["error"] == "There is no series 'nope/nothing' in this log."
    bad_points = client.get(url, {"path": "navdata/Altitude", "points": "0"})
    assert bad_points.status_code == 400 and bad_points.json()["fields"]["points"]
    bad_start = client.get(url, {"path": "navdata/Altitude", "start": "nan"})
    assert bad_start.status_code == 400 and bad_start.json()["code"] == "invalid"


def test_values_at_a_time_are_the_last_sample_of_every_series(world_tx, worker, tmp_path):
    client = client_for(world_tx.operator)
    body = processed(client, make_log("dfi", tmp_path))
    values = client.get(f"/api/v1/logs/{body['id']}/values/", {"t": 0.0025}).json()["values"]
    assert values["navdata"]["Altitude"] == {"t": 0.002, "value": 0.75, "label": None}
    assert values["navdata"]["state"]["label"] == "Flying"
    assert values["navdata"]["Motor powers"]["motor 2"]["value"] == 121
    assert values["commands"]["Velocity"]["x"] is None  # starts at 5 ms


def test_timeline_track_and_attitude_serve_the_viewer(world_tx, worker, tmp_path):
    client = client_for(world_tx.operator)
    body = processed(client, make_log("ulg", tmp_path))
    base = f"/api/v1/logs/{body['id']}"
    timeline = client.get(f"{base}/timeline/", {"bins": 40}).json()
    assert {layer["name"] for layer in timeline["layers"]} == {
        layer["name"] for layer in body["layers"]
    }
    imu = next(x for x in timeline["layers"] if x["name"] == "sensor_combined")
    assert len(imu["counts"]) == 40 and sum(imu["counts"]) == 1000

    track = client.get(f"{base}/track/").json()
    assert track["source"] in ("gps", "estimated")
    attitude = client.get(f"{base}/attitude/").json()
    assert len(attitude["t"]) == len(attitude["roll"]) == len(attitude["yaw"]) == 1000


def test_a_log_without_gps_gets_the_estimated_trajectory(world_tx, worker, tmp_path):
    client = client_for(world_tx.operator)
    body = processed(client, make_log("bag", tmp_path))
    track = client.get(f"/api/v1/logs/{body['id']}/track/").json()
    assert track["source"] == "estimated"
    assert len(track["x"]) == len(track["y"]) == len(track["t"]) > 10
    assert track["x"][0] == 0 and track["y"][0] == 0
    assert any(abs(y) > 0 for y in track["y"])


def test_logs_are_listed_newest_first_and_searched_by_name(world_tx, worker, tmp_path):
    client = client_for(world_tx.operator)
    first = processed(client, make_log("dfi", tmp_path))
    renamed = tmp_path / "crash-tuesday.tlog"
    make_log("tlog", tmp_path).rename(renamed)
    second = processed(client, renamed)
    listed = client.get("/api/v1/logs/").json()
    assert [x["id"] for x in listed["results"]] == [second["id"], first["id"]]
    found = client.get("/api/v1/logs/", {"q": "crash"}).json()
    assert [x["id"] for x in found["results"]] == [second["id"]]
    assert found["results"][0]["url"] == f"/logs/{second['id']}/"


# --- bad input: a clear error, nothing half-imported, the worker keeps running ---


def _assert_failed_cleanly(body: dict, logs_dir: Path, world, message: str) -> None:  # type: ignore[no-untyped-def]
    assert body["status"] == "failed", body
    assert message in body["error"], body["error"]
    assert body["series"] == [] and body["format"] == ""
    assert not (logs_dir / str(world.org.pk) / body["id"] / "store").exists()


def _bomb(path: Path) -> Path:
    rows = "1000,5,0.5,1.5,-2.25,90.0,100,101,2\n" * 400_000  # 14 MB of one repeated line
    return write_dfi(path, {"navdata.csv": rows})


def _laughs(path: Path) -> Path:
    entities = '<!ENTITY a "hahahahahahahahahahahaha">' + "".join(
        f'<!ENTITY {chr(98 + i)} "{("&" + chr(97 + i) + ";") * 10}">' for i in range(8)
    )
    description = DESCRIPTION.replace(
        "<recording>", f"<!DOCTYPE recording [{entities}]>\n<recording>"
    ).replace('name="navdata"', 'name="&i;"')
    return write_dfi(path, description=description)


@pytest.mark.parametrize(
    ("name", "build", "message"),
    [
        ("garbage.ulg", lambda p: p.write_bytes(b"garbage" * 100), "not a valid PX4 ULog"),
        (
            "cut.bin",
            lambda p: (synthetic_dataflash(p, seconds=2), p.write_bytes(p.read_bytes()[:90])),
            "flight.bin",
        ),
        (
            "half.dfi",
            lambda p: (write_dfi(p), p.write_bytes(p.read_bytes()[: p.stat().st_size // 2])),
            "",
        ),
        ("bomb.dfi", _bomb, "ZIP bomb"),
        ("laughs.dfi", _laughs, "description.xml"),
        (
            "columns.dfi",
            lambda p: write_dfi(p, {"navdata.csv": "1000,5,0.5,1.5,-2.25,90.0,100,101,2,9\n"}),
            "columns",
        ),
    ],
    ids=["corrupt", "truncated", "truncated-zip", "zip-bomb", "entity-expansion", "columns"],
)
def test_bad_files_fail_with_a_clear_error_and_leave_nothing_behind(
    world_tx, worker, tmp_path, logs_dir, name, build, message
):
    path = tmp_path / name
    build(path)
    if name == "cut.bin":
        path = path.rename(tmp_path / "flight.bin")
    body = processed(client_for(world_tx.operator), path)
    _assert_failed_cleanly(body, logs_dir, world_tx, message)
    assert body["error"].endswith(".") and len(body["error"]) > 20
    assert worker.alive


def test_the_worker_still_imports_after_bad_files(world_tx, worker, tmp_path):
    client = client_for(world_tx.operator)
    bad = tmp_path / "bad.ulg"
    bad.write_bytes(b"ULog\x01\x12\x35\x01" + b"\xff" * 5000)
    assert processed(client, bad)["status"] == "failed"
    assert processed(client, make_log("dfi", tmp_path))["status"] == "ready"
    assert worker.alive


def test_a_file_of_no_known_format_is_refused_at_upload(world_tx, tmp_path, logs_dir):
    path = tmp_path / "holiday.jpg"
    path.write_bytes(b"\xff\xd8\xff\xe0 not a flight log" * 10)
    response = upload(client_for(world_tx.operator), path)
    assert response.status_code == 400
    body = response.json()
    assert "'holiday.jpg' is not a flight log format we can read" in body["error"]
    assert body["fields"]["file"]
    assert not list((logs_dir / "incoming").glob("*"))
    assert client_for(world_tx.operator).get("/api/v1/logs/").json()["count"] == 0


def test_an_upload_over_the_limit_is_refused_with_413(world_tx, tmp_path, logs_dir, settings):
    settings.LOG_UPLOAD_MAX_BYTES = 20_000
    path = make_log("ulg", tmp_path)
    assert path.stat().st_size > 100_000  # refused on Content-Length, before parsing
    response = upload(client_for(world_tx.operator), path)
    assert response.status_code == 413
    assert response.json() == {
        "error": "The file is larger than the upload limit of 19.5 KB.",
        "code": "too_large",
        "fields": {},
    }
    assert not list((logs_dir / "incoming").glob("*"))
    assert client_for(world_tx.operator).get("/api/v1/logs/").json()["count"] == 0


def test_an_upload_past_the_limit_is_cut_off_while_it_streams(world_tx, tmp_path, settings):
    """Within the multipart slack the announced length passes; the handler counts bytes."""
    settings.LOG_UPLOAD_MAX_BYTES = 10_000
    path = tmp_path / "long.ulg"
    path.write_bytes(b"ULog" + b"U" * 50_000)
    response = upload(client_for(world_tx.operator), path)
    assert response.status_code == 413
    assert response.json()["code"] == "too_large"
    assert not list((Path(settings.LOGS_DIR) / "incoming").glob("*"))


def test_an_upload_without_a_file_says_what_is_missing(world):
    response = client_for(world.operator).post("/api/v1/logs/", {"name": "x"})
    assert response.status_code == 400
    assert response.json()["fields"] == {"file": ["Choose a flight log file to upload."]}


# --- organisations and roles ---


@pytest.fixture
def ready_log(world_tx, worker, tmp_path):  # type: ignore[no-untyped-def]
    return processed(client_for(world_tx.operator), make_log("dfi", tmp_path))


def test_outsiders_get_404_for_everything_about_a_log(world_tx, ready_log):
    outsider = client_for(world_tx.outsider)
    base = f"/api/v1/logs/{ready_log['id']}"
    for url in (f"{base}/", f"{base}/series/?path=navdata/Altitude", f"{base}/values/?t=1"):
        assert outsider.get(url).status_code == 404
    assert outsider.delete(f"{base}/").status_code == 404
    assert outsider.get(f"/logs/{ready_log['id']}/").status_code == 404
    assert outsider.get("/api/v1/logs/").json()["count"] == 0


def test_viewers_read_but_cannot_delete_or_upload(world_tx, ready_log, tmp_path):
    viewer = client_for(world_tx.viewer)
    assert viewer.get(f"/api/v1/logs/{ready_log['id']}/").json()["status"] == "ready"
    assert viewer.get(f"/logs/{ready_log['id']}/").status_code == 200
    refused = viewer.delete(f"/api/v1/logs/{ready_log['id']}/")
    assert refused.status_code == 403 and refused.json()["code"] == "permission_denied"
    upload_refused = upload(viewer, make_log("dfi", tmp_path))
    assert upload_refused.status_code == 403
    assert upload_refused.json()["error"] == "Uploading logs needs the operator role."


def test_operators_delete_a_log_and_its_files(world_tx, ready_log, logs_dir):
    folder = logs_dir / str(world_tx.org.pk) / ready_log["id"]
    assert (folder / "store" / "index.json").exists()
    client = client_for(world_tx.operator)
    assert client.delete(f"/api/v1/logs/{ready_log['id']}/").status_code == 204
    assert client.get(f"/api/v1/logs/{ready_log['id']}/").status_code == 404
    assert not folder.exists()


def test_the_share_link_opens_for_every_member_of_the_organisation(world_tx, ready_log):
    page = client_for(world_tx.owner).get(f"/logs/{ready_log['id']}/")
    assert page.status_code == 200
    assert f"http://testserver/logs/{ready_log['id']}/" in page.content.decode()


def test_the_list_page_shows_the_organisations_logs_and_an_upload_zone(world_tx, ready_log):
    page = client_for(world_tx.operator).get("/logs/").content.decode()
    assert "flight.dfi" in page and 'type="file"' in page
    viewer_page = client_for(world_tx.viewer).get("/logs/").content.decode()
    assert "flight.dfi" in viewer_page and 'type="file"' not in viewer_page
    assert "flight.dfi" not in client_for(world_tx.outsider).get("/logs/").content.decode()


def test_a_member_of_zip_member_extension_is_taken_from_the_upload(world_tx, worker, tmp_path):
    """A DFI uploaded as .zip is still read as DFI (content before extension)."""
    path = write_dfi(tmp_path / "recording.zip")
    assert zipfile.is_zipfile(path)
    body = processed(client_for(world_tx.operator), path)
    assert body["status"] == "ready" and body["format"] == "dfi"


@pytest.mark.parametrize("name", ["sample_log_small.ulg", "sample_appended_multiple.ulg"])
def test_real_px4_logs_serve_the_values_pyulog_reads(world_tx, worker, tmp_path, name):
    from pyulog import ULog

    source = REAL_LOGS / name
    path = tmp_path / name
    path.write_bytes(source.read_bytes())
    client = client_for(world_tx.operator)
    body = processed(client, path)
    assert body["status"] == "ready", body
    base = f"/api/v1/logs/{body['id']}"

    reference = ULog(str(source)).get_dataset("vehicle_attitude")
    layer = next(x["name"] for x in body["layers"] if x["name"].startswith("vehicle_attitude"))
    served = client.get(f"{base}/series/", {"path": f"{layer}/q[0]"}).json()
    assert served["v"] == reference.data["q[0]"].tolist()
    assert served["t"] == pytest.approx((reference.data["timestamp"] / 1e6).tolist())

    stamps = reference.data["timestamp"].astype(np.int64)
    gaps = np.flatnonzero(np.diff(stamps) > 0)
    last = int(gaps[len(gaps) // 2])  # a sample followed by a later one
    at = (stamps[last] + stamps[last + 1]) / 2e6  # between two samples: no rounding at the edge
    values = client.get(f"{base}/values/", {"t": at})
    assert values.status_code == 200  # NaNs in real logs come back as null, not a 500
    assert values.json()["values"][layer]["q[0]"]["value"] == reference.data["q[0]"][last].item()
    assert client.get(f"{base}/attitude/").json()["t"]


def test_a_mission_log_gives_one_gps_track_per_drone(world_tx, worker, tmp_path):
    client = client_for(world_tx.operator)
    body = processed(client, make_log("json", tmp_path))
    track = client.get(f"/api/v1/logs/{body['id']}/track/").json()
    assert track["source"] == "gps"
    assert [t["name"] for t in track["tracks"]] == ["drone Alpha", "drone Bravo"]
    assert track["tracks"][1]["lat"][0] == pytest.approx(51.0)
    assert track["lat"] == track["tracks"][0]["lat"]


def test_partial_uploads_abandoned_for_a_day_are_swept_by_the_next_upload(
    world_tx, tmp_path, logs_dir
):
    import os
    import time

    incoming = logs_dir / "incoming"
    incoming.mkdir(exist_ok=True)
    abandoned, recent = incoming / "abandoned.part", incoming / "recent.part"
    abandoned.write_bytes(b"x" * 100)
    recent.write_bytes(b"y" * 100)
    two_days_ago = time.time() - 2 * 86400
    os.utime(abandoned, (two_days_ago, two_days_ago))
    assert upload(client_for(world_tx.operator), make_log("dfi", tmp_path)).status_code == 201
    assert not abandoned.exists() and recent.exists()
    recent.unlink()


def test_token_clients_in_several_organisations_must_name_one(world_tx, tmp_path):
    from rest_framework.authtoken.models import Token
    from rest_framework.test import APIClient

    from fleet.models import Membership, Role

    Membership.objects.create(
        user=world_tx.operator, organisation=world_tx.other_org, role=Role.OPERATOR
    )
    client = APIClient()
    client.credentials(HTTP_AUTHORIZATION=f"Token {Token.objects.create(user=world_tx.operator)}")
    path = make_log("dfi", tmp_path)
    with open(path, "rb") as f:
        ambiguous = client.post("/api/v1/logs/", {"file": f}, format="multipart")
    assert ambiguous.status_code == 400 and "organisation" in ambiguous.json()["fields"]
    with open(path, "rb") as f:
        named = client.post(
            "/api/v1/logs/", {"file": f, "organisation": "globex"}, format="multipart"
        )
    assert named.status_code == 201
    assert client.get(f"/api/v1/logs/{named.json()['id']}/").json()["organisation"] == "globex"


def test_members_download_the_original_file_and_outsiders_get_404(world_tx, tmp_path):
    path = make_log("dfi", tmp_path)
    created = upload(client_for(world_tx.operator), path).json()
    response = client_for(world_tx.viewer).get(f"/logs/{created['id']}/download/")
    assert response.status_code == 200
    assert b"".join(response.streaming_content) == path.read_bytes()
    assert 'filename="flight.dfi"' in response["Content-Disposition"]
    assert client_for(world_tx.outsider).get(f"/logs/{created['id']}/download/").status_code == 404
