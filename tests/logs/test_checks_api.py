"""The health report and spectra over the API: run by the import worker, read by members
of the log's organisation only, with links into the viewer and bounded spectra."""

from __future__ import annotations

import json
from urllib.parse import unquote

import pytest
from django.test import Client

from logs.checks import CHECKS
from logs.synth_faults import FAULT_AT, ardupilot_bin, px4_ulog
from tests.logs.conftest import upload, wait_until_processed

pytestmark = [pytest.mark.e2e, pytest.mark.usefixtures("logs_settings")]
# Every check's fields, as the API contract names them.
CONTRACT = ("check", "status", "value", "unit", "threshold", "t", "reason")


def client_for(user) -> Client:  # type: ignore[no-untyped-def]
    client = Client()
    client.force_login(user)
    return client


@pytest.fixture
def motor_log(world_tx, worker, tmp_path):  # type: ignore[no-untyped-def]
    client = client_for(world_tx.operator)
    created = upload(client, px4_ulog(tmp_path / "motor.ulg", {"motor"})).json()
    body = wait_until_processed(client, created["id"])
    assert body["status"] == "ready", body
    return body


def test_the_import_keeps_the_report_and_members_read_it(world_tx, motor_log, logs_dir):
    from logs.models import FlightLog

    log = FlightLog.objects.get(pk=motor_log["id"])
    kept = json.loads((log.directory / "checks.json").read_text())
    assert [c["name"] for c in kept["checks"]] == list(CHECKS)
    response = client_for(world_tx.viewer).get(f"/api/v1/logs/{log.pk}/checks/")
    assert response.status_code == 200
    checks = {c["check"]: c for c in response.json()["checks"]}
    assert list(checks) == list(CHECKS)
    assert all(set(CONTRACT) <= set(c) and c["name"] == n for n, c in checks.items())
    motors = checks["motor_imbalance"]
    assert motors["status"] == "fail"
    assert motors["t"] == pytest.approx(FAULT_AT["motor"], abs=0.1)
    # The link opens this log's viewer at that moment, around it, on the motor outputs.
    path, _, fragment = motors["link"].partition("#")
    assert path == f"/logs/{log.pk}/"
    params = dict(part.split("=", 1) for part in fragment.split("&"))
    assert float(params["t"]) == pytest.approx(motors["t"], abs=1e-3)
    lo, hi = (float(x) for x in params["view"].split("~"))
    assert lo < motors["t"] < hi
    assert [unquote(p) for p in params["plot"].split(",")][:4] == [
        f"actuator_outputs/output[{i}]" for i in range(4)
    ]
    assert {c["status"] for n, c in checks.items() if n != "motor_imbalance"} == {"pass"}


def test_outsiders_get_404_for_checks_and_spectra(world_tx, motor_log):
    outsider = client_for(world_tx.outsider)
    base = f"/api/v1/logs/{motor_log['id']}"
    assert outsider.get(f"{base}/checks/").status_code == 404
    spectrum = f"{base}/spectrum/?series=sensor_combined/accelerometer_m_s2[2]"
    assert outsider.get(spectrum).status_code == 404


def test_organisation_thresholds_apply_to_its_logs(world_tx, motor_log, settings):
    from logs.models import FlightLog

    log = FlightLog.objects.get(pk=motor_log["id"])
    settings.LOGS_CHECK_THRESHOLDS = {
        "*": {"cpu_load": {"warning": 0.3}},
        world_tx.org.slug: {"vibration": {"px4": {"warning": 1.0}}},
        "someone-else": {"battery_sag": {"warning": 4.0}},
    }
    (log.directory / "checks.json").unlink()  # made again on the next read
    checks = {
        c["name"]: c
        for c in client_for(world_tx.viewer).get(f"/api/v1/logs/{log.pk}/checks/").json()["checks"]
    }
    assert checks["vibration"]["status"] == "warning"
    assert checks["vibration"]["threshold"]["warning"] == 1.0
    assert checks["cpu_load"]["status"] == "warning"
    assert checks["battery_sag"]["status"] == "pass"


def test_the_spectrum_of_any_series_over_a_window(world_tx, motor_log):
    client = client_for(world_tx.viewer)
    base = f"/api/v1/logs/{motor_log['id']}/spectrum/"
    response = client.get(
        base,
        {
            "series": "sensor_combined/accelerometer_m_s2[2],actuator_outputs/output[0]",
            "start": 10,
            "end": 30,
        },
    )
    assert response.status_code == 200, response.content
    body = response.json()
    accel, motor = body["series"]
    assert accel["fs"] == pytest.approx(200, rel=1e-3)
    assert accel["frequency"][-1] == pytest.approx(100, rel=1e-3)
    assert len(accel["psd"]) == len(accel["frequency"]) == 129
    assert accel["segments"] == (20 * 200 - 256) // 128 + 1
    assert accel["unit"] == "(m/s²)²/Hz" or accel["unit"].endswith("/Hz")
    assert motor["fs"] == pytest.approx(50, rel=1e-3)


@pytest.mark.parametrize(
    ("query", "status", "field"),
    [
        ({}, 400, "series"),
        ({"series": "nothing/here"}, 404, None),
        ({"series": "sensor_combined/accelerometer_m_s2[2]", "nperseg": "3"}, 400, "series"),
        ({"series": "sensor_combined/accelerometer_m_s2[2]", "nperseg": "x"}, 400, "nperseg"),
        ({"series": "sensor_combined/accelerometer_m_s2[2]", "start": "nan"}, 400, "start"),
        ({"series": ",".join(["sensor_combined/accelerometer_m_s2[2]"] * 7)}, 400, "series"),
        (
            {"series": "sensor_combined/accelerometer_m_s2[2]", "start": 10, "end": 10.05},
            400,
            "series",
        ),
    ],
)
def test_bad_spectrum_requests_say_what_is_wrong(world_tx, motor_log, query, status, field):
    response = client_for(world_tx.viewer).get(f"/api/v1/logs/{motor_log['id']}/spectrum/", query)
    assert response.status_code == status, response.content
    if field:
        assert field in json.dumps(response.json())


def test_a_log_imported_before_checks_gets_its_report_when_asked(world_tx, worker, tmp_path):
    from logs.models import FlightLog

    client = client_for(world_tx.operator)
    created = upload(client, ardupilot_bin(tmp_path / "gps.bin", {"gps"})).json()
    assert wait_until_processed(client, created["id"])["status"] == "ready"
    log = FlightLog.objects.get(pk=created["id"])
    (log.directory / "checks.json").unlink()
    checks = {c["name"]: c for c in client.get(f"/api/v1/logs/{log.pk}/checks/").json()["checks"]}
    assert checks["gps"]["status"] == "fail"
    assert checks["gps"]["t"] == pytest.approx(FAULT_AT["gps"], abs=0.25)
    assert (log.directory / "checks.json").exists()


def test_the_openapi_schema_lists_checks_and_spectrum(world):
    response = client_for(world.operator).get("/api/schema/", HTTP_ACCEPT="application/json")
    assert response.status_code == 200
    text = response.content.decode()
    assert "/api/v1/logs/{id}/checks/" in text
    assert "/api/v1/logs/{id}/spectrum/" in text
    assert "FlightLogCheck" in text and "FlightLogSpectrum" in text


def test_airframe_thresholds_apply_to_the_logs_of_that_airframe(
    world_tx, worker, tmp_path, settings
):
    from logs.models import FlightLog

    client = client_for(world_tx.operator)
    path = ardupilot_bin(tmp_path / "hexa.bin", parameters={"FRAME_CLASS": 2, "MOT_PWM_MAX": 1950})
    created = upload(client, path).json()
    assert wait_until_processed(client, created["id"])["status"] == "ready"
    log = FlightLog.objects.get(pk=created["id"])
    settings.LOGS_CHECK_THRESHOLDS = {
        f"{world_tx.org.slug}/airframe:2": {"vibration": {"ardupilot": {"warning": 10.0}}},
        f"{world_tx.org.slug}/airframe:1": {"battery_sag": {"warning": 4.0}},
    }
    (log.directory / "checks.json").unlink()
    body = client.get(f"/api/v1/logs/{log.pk}/checks/").json()
    assert body["airframe"] == "2"
    checks = {c["name"]: c for c in body["checks"]}
    assert checks["vibration"]["status"] == "warning"
    assert checks["vibration"]["threshold"] == {"warning": 10.0, "fail": 60.0}
    assert checks["battery_sag"]["status"] == "pass"


def test_bad_threshold_settings_are_named_by_the_system_check(settings):
    from logs.apps import check_thresholds_setting

    settings.LOGS_CHECK_THRESHOLDS = {"*": {"vibration": {"px4": {"warning": 1}}}}
    assert check_thresholds_setting(None) == []
    settings.LOGS_CHECK_THRESHOLDS = {"acme": {"vibrations": {}}, "*": {"gps": {"outage_s": "1"}}}
    errors = check_thresholds_setting(None)
    assert [e.id for e in errors] == ["logs.E001", "logs.E001"]
    assert "LOGS_CHECK_THRESHOLDS['acme']: vibrations: no such threshold" in errors[0].msg
    assert "gps.outage_s: expected a number" in errors[1].msg


def test_the_list_page_shows_each_logs_health(world_tx, motor_log, logs_dir):
    import re

    page = client_for(world_tx.viewer).get("/logs/").content.decode()
    row = re.search(rf'<tr data-log="{motor_log["id"]}">.*?</tr>', page, re.S).group(0)
    assert '<span class="badge bad">1 failed</span>' in row
    assert client_for(world_tx.outsider).get("/logs/").status_code in (200, 404)
    assert motor_log["id"] not in client_for(world_tx.outsider).get("/logs/").content.decode()
