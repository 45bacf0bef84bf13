"""The automatic log checks on logs with known faults, written in each format's own
structure (logs/synth_faults.py), on PX4's own sample logs, and on logs without
the topics a check needs."""

from __future__ import annotations

import numpy as np
import pytest
from pyulog import ULog

from logs.checks import CHECKS, merged, run_checks
from logs.checks.signals import ema, px4_accel_vibration
from logs.checks.thresholds import ThresholdError
from logs.store import import_to_store
from logs.synth import write_ulog
from logs.synth_faults import (
    EXPECTED,
    FAULT_AT,
    FAULTS,
    ardupilot_bin,
    mavlink_tlog,
    px4_ulog,
)
from tests.support.paths import REAL_ULOGS

WRITERS = {
    "ulog": (px4_ulog, "ulg"),
    "dataflash": (ardupilot_bin, "bin"),
    "tlog": (mavlink_tlog, "tlog"),
}


def _checks(tmp_path, path, thresholds=None) -> dict[str, dict]:
    store = import_to_store(path, tmp_path / f"store-{path.name}")
    results = run_checks(store, thresholds)
    assert [r["name"] for r in results] == list(CHECKS)
    return {r["name"]: r for r in results}


@pytest.mark.parametrize("fmt", WRITERS)
def test_a_clean_flight_passes_every_check(tmp_path, fmt):
    writer, ext = WRITERS[fmt]
    results = _checks(tmp_path, writer(tmp_path / f"clean.{ext}"))
    assert {name: r["status"] for name, r in results.items()} == dict.fromkeys(CHECKS, "pass")
    assert results["vibration"]["value"] > 0
    assert results["battery_sag"]["unit"] == "V/cell"


@pytest.mark.parametrize("fault", FAULTS)
@pytest.mark.parametrize("fmt", WRITERS)
def test_each_fault_is_reported_at_its_time_with_its_severity(tmp_path, fmt, fault):
    writer, ext = WRITERS[fmt]
    results = _checks(tmp_path, writer(tmp_path / f"{fault}.{ext}", {fault}))
    expected = EXPECTED[fault]
    for name, result in results.items():
        if name in expected:
            assert result["status"] == expected[name], result
            # Reported where the fault began (records come at 5 to 25 Hz).
            assert result["t"] == pytest.approx(FAULT_AT[fault], abs=0.25), result
            assert result["series"], result
            lo, hi = result["window"]
            assert lo <= result["t"] <= hi
        else:
            assert result["status"] == "pass", result


def test_findings_name_their_figures(tmp_path):
    results = _checks(tmp_path, px4_ulog(tmp_path / "all.ulg", set(FAULTS)))
    assert results["battery_sag"]["value"] == pytest.approx(3.2, abs=1e-3)
    assert results["battery_sag"]["threshold"] == {"warning": 3.5, "fail": 3.3}
    assert results["clipping"]["value"] == 600
    assert results["gps"]["value"] == pytest.approx(4.0, abs=0.25)  # outage length, s
    assert results["gps"]["unit"] == "s"
    assert results["motor_imbalance"]["value"] == pytest.approx(5.0, abs=0.1)
    assert "output[2]" in results["motor_imbalance"]["reason"]
    assert results["rc_loss"]["value"] == pytest.approx(2.0, abs=0.25)


def test_a_log_without_the_topics_is_not_checked_with_the_reason(tmp_path):
    path = px4_ulog(tmp_path / "bare.ulg", topics={"sensor_combined"})
    results = _checks(tmp_path, path)
    for name in (
        "clipping",
        "gps",
        "battery_sag",
        "rc_loss",
        "motor_imbalance",
        "estimator",
        "failsafe",
        "cpu_load",
    ):
        assert results[name]["status"] == "not_checked", results[name]
        assert results[name]["reason"].startswith("no "), results[name]
    # Vibration is recomputed from sensor_combined as PX4 does on board.
    assert results["vibration"]["status"] == "pass"
    assert "recomputed from sensor_combined" in results["vibration"]["reason"]


def test_a_log_with_unrelated_topics_is_not_checked_rather_than_passed(tmp_path):
    arr = np.zeros(600, dtype=[("timestamp", "<u8"), ("indicated_airspeed_m_s", "<f4")])
    arr["timestamp"] = np.arange(600) * 100_000
    path = tmp_path / "airspeed.ulg"
    write_ulog(path, {"airspeed": arr})
    results = _checks(tmp_path, path)
    assert results["logging_dropouts"]["status"] == "pass"
    assert {r["status"] for n, r in results.items() if n != "logging_dropouts"} == {"not_checked"}
    assert results["vibration"]["reason"].startswith("no vehicle_imu_status")


def test_a_log_too_short_is_not_checked(tmp_path):
    arr = np.zeros(5, dtype=[("timestamp", "<u8"), ("load", "<f4")])
    arr["timestamp"] = np.arange(5) * 100_000
    path = tmp_path / "short.ulg"
    write_ulog(path, {"cpuload": arr})
    results = _checks(tmp_path, path)
    assert {r["status"] for r in results.values()} == {"not_checked"}
    assert results["cpu_load"]["reason"].startswith("log too short")


def test_thresholds_are_overridable_and_checked(tmp_path):
    path = px4_ulog(tmp_path / "clean.ulg")
    strict = merged({"vibration": {"px4": {"warning": 1.0}}, "battery_sag": {"warning": 3.9}})
    results = _checks(tmp_path, path, strict)
    assert results["vibration"]["status"] == "warning"
    assert results["vibration"]["threshold"] == {"warning": 1.0, "fail": 9.81}
    assert results["battery_sag"]["status"] == "warning"
    assert results["battery_sag"]["t"] == pytest.approx(5.0 + 50 * 0.05 / 0.2, abs=0.2)
    with pytest.raises(ThresholdError, match="vibration.px4.warn: no such threshold"):
        merged({"vibration": {"px4": {"warn": 1.0}}})
    with pytest.raises(ThresholdError, match="expected a number"):
        merged({"clipping": {"fail": "many"}})


def test_ema_matches_the_recursion():
    x = np.random.default_rng(1).random(10_000)
    expected, y = np.empty_like(x), 0.0
    for i, v in enumerate(x):
        y = 0.99 * y + 0.01 * v
        expected[i] = y
    np.testing.assert_allclose(ema(x, 0.01), expected, rtol=1e-9)


# --- PX4's own sample logs ---


def _flight_review_vibration(path) -> float:
    """Flight Review's Vibration Metrics plot (plot_app/configured_plots.py): every
    vehicle_imu_status instance's accel_vibration_metric; the figure is its highest value
    while armed (vehicle_status.arming_state 2), read here with pyulog."""
    ulog = ULog(str(path))
    status = ulog.get_dataset("vehicle_status").data
    peaks = []
    for d in ulog.data_list:
        if d.name != "vehicle_imu_status":
            continue
        idx = np.searchsorted(status["timestamp"], d.data["timestamp"], side="right") - 1
        armed = (idx >= 0) & (status["arming_state"][np.maximum(idx, 0)] == 2)
        peaks.append(float(np.max(d.data["accel_vibration_metric"][armed])))
    return max(peaks)


def test_real_px4_log_vibration_equals_flight_reviews_figure(tmp_path):
    path = REAL_ULOGS / "sample_log_small.ulg"
    results = _checks(tmp_path, path)
    vib = results["vibration"]
    assert vib["value"] == pytest.approx(_flight_review_vibration(path), rel=1e-6)
    # PX4 v1.12 kept the metric on delta velocity (m/s): Flight Review's bands then.
    assert vib["unit"] == "m/s" and vib["status"] == "pass"
    assert vib["series"][0].startswith("vehicle_imu_status_")
    assert set(r["status"] for r in results.values()) <= {"pass", "warning", "not_checked"}


def test_real_px4_logs_give_a_verdict_for_what_they_record(tmp_path):
    small = _checks(tmp_path, REAL_ULOGS / "sample_log_small.ulg")
    assert small["clipping"]["status"] == "pass"
    assert small["estimator"]["status"] == "pass"
    assert small["failsafe"]["status"] == "pass"
    # A VTOL: its outputs mix motors and control surfaces.
    assert small["motor_imbalance"]["reason"].startswith("not a multicopter")
    appended = _checks(tmp_path, REAL_ULOGS / "sample_appended_multiple.ulg")
    assert appended["gps"]["status"] == "not_checked"
    assert appended["battery_sag"]["status"] == "not_checked"


def test_recomputed_vibration_follows_px4s_metric_on_a_full_rate_stream():
    """The fallback metric on sensor_combined is PX4's own filter: on samples it computes
    exactly the recursion VehicleIMU runs."""
    rng = np.random.default_rng(2)
    acc = rng.normal(0, 1.0, size=(4000, 3))
    metric, expected = px4_accel_vibration(*acc.T), [0.0]
    for k in range(1, len(acc)):
        expected.append(0.99 * expected[-1] + 0.01 * float(np.linalg.norm(acc[k] - acc[k - 1])))
    np.testing.assert_allclose(metric, expected, rtol=1e-9)
    # Unit white noise per axis: the change between samples is sqrt(2) times a 3D
    # standard normal, whose length averages 2 sqrt(2/pi): 4/sqrt(pi), about 2.26 m/s².
    assert np.mean(metric[2000:]) == pytest.approx(2.26, rel=0.05)


def test_the_faults_are_in_the_files_as_the_formats_own_readers_see_them(tmp_path):
    """pyulog and pymavlink (the readers PX4 Flight Review and ArduPilot's tools use) find
    each fault where the checks report it."""
    from pymavlink import mavutil

    ulog = ULog(str(px4_ulog(tmp_path / "px4.ulg", {"clipping", "motor"})))
    imu = ulog.get_dataset("vehicle_imu_status").data
    first_clip = imu["timestamp"][np.argmax(imu["accel_clipping[2]"] > 0)] / 1e6
    assert first_clip == pytest.approx(FAULT_AT["clipping"]) and imu["accel_clipping[2]"][-1] == 600
    outputs = ulog.get_dataset("actuator_outputs").data
    pinned = outputs["timestamp"][outputs["output[2]"] == 2000] / 1e6
    assert pinned.min() == pytest.approx(FAULT_AT["motor"])

    conn = mavutil.mavlink_connection(str(ardupilot_bin(tmp_path / "ap.bin", {"gps", "rc"})))
    seen: dict[str, list] = {}
    while (msg := conn.recv_match(type=["GPS", "ERR"])) is not None:
        seen.setdefault(msg.get_type(), []).append(msg)
    lost = [m.TimeUS / 1e6 for m in seen["GPS"] if m.Status < 3]
    assert min(lost) == pytest.approx(FAULT_AT["gps"])
    assert [(m.TimeUS / 1e6, m.Subsys, m.ECode) for m in seen["ERR"]] == [
        (FAULT_AT["rc"], 5, 1),
        (FAULT_AT["rc"] + 2.0, 5, 0),
    ]


def test_ardupilot_parameters_come_from_parm_records(tmp_path):
    from logs.checks.base import LogView

    path = ardupilot_bin(tmp_path / "p.bin", parameters={"MOT_PWM_MIN": 1100, "MOT_PWM_MAX": 1900})
    view = LogView(import_to_store(path, tmp_path / "store"))
    assert view.parameter("PWM_MAIN_MAX", "MOT_PWM_MAX") == 1900
    assert view.parameter("NO_SUCH") is None
    # Hovering at 1500 µs is now half of 1100-1900: no motor sits at its limit.
    results = {r["name"]: r for r in run_checks(view.store)}
    assert results["motor_imbalance"]["status"] == "pass"


def test_a_check_that_breaks_is_reported_and_the_others_still_run(tmp_path):
    path = px4_ulog(tmp_path / "clean.ulg")
    levels = merged()
    del levels["gps"]  # the gps check now fails to read its thresholds
    results = _checks(tmp_path, path, levels)
    assert results["gps"]["status"] == "not_checked"
    assert results["gps"]["reason"] == "the check could not read this log (KeyError)"
    assert {r["status"] for n, r in results.items() if n != "gps"} == {"pass"}


def test_the_ulog_loggers_own_dropouts_are_reported(tmp_path):
    """PX4's sample log records one dropout of 30 ms (pyulog reads the same)."""
    path = REAL_ULOGS / "sample_log_small.ulg"
    assert sum(d.duration for d in ULog(str(path)).dropouts) == 30
    result = _checks(tmp_path, path)["logging_dropouts"]
    assert result["status"] == "warning"
    assert "the logger dropped 30 ms of data" in result["reason"]
