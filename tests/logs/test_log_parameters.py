"""Parameters of two logs as a diff (PX4 ULog, ArduPilot .bin, dRonin settings objects in
the agent's DFI), against a saved reference per drone model, the two logs' take-off
times for one time axis, and the refusals: another organisation's log, a log without
parameters."""

from __future__ import annotations

from pathlib import Path

import pytest

from logs.compare import takeoff
from logs.parameters import diff, read_parameters
from logs.store import import_to_store, open_store
from logs.synth_faults import ARM_AT, ardupilot_bin, mavlink_tlog, px4_ulog
from onboard.logger import FlightLogger
from tests.logs.test_trends import client_for, imported

DATA = Path(__file__).resolve().parents[1] / "data" / "ulog"
PX4_A = {"SYS_AUTOSTART": 4001, "MC_ROLL_P": 6.5, "MPC_XY_VEL_MAX": 12.0, "BAT_N_CELLS": 4}
PX4_B = {"SYS_AUTOSTART": 4001, "MC_ROLL_P": 7.0, "MPC_XY_VEL_MAX": 12.0, "COM_RC_LOSS_T": 0.5}


def store_of(path: Path, tmp_path: Path):  # type: ignore[no-untyped-def]
    out = tmp_path / f"{path.name}.store"
    import_to_store(path, out)
    return open_store(out)


def test_ardupilot_parameters_of_two_bins_differ_where_they_were_changed(tmp_path):
    a = store_of(
        ardupilot_bin(
            tmp_path / "a.bin",
            parameters={"FRAME_CLASS": 1, "ATC_RAT_RLL_P": 0.135, "INS_ACCEL_FILTER": 20},
        ),
        tmp_path,
    )
    b = store_of(
        ardupilot_bin(
            tmp_path / "b.bin",
            parameters={"FRAME_CLASS": 1, "ATC_RAT_RLL_P": 0.15, "INS_ACCEL_FILTER": 20},
        ),
        tmp_path,
    )
    pa, pb = read_parameters(a), read_parameters(b)
    assert (pa.autopilot, pa.airframe, pa.source) == ("ardupilot", "1", "PARM")
    assert diff(pa.values, pb.values) == [
        {"name": "ATC_RAT_RLL_P", "a": 0.135, "b": 0.15, "change": "changed"}
    ]


def test_px4_sample_logs_differ_and_dronin_settings_objects_are_parameters(tmp_path):
    small = read_parameters(store_of(DATA / "sample_log_small.ulg", tmp_path))
    appended = read_parameters(store_of(DATA / "sample_appended_multiple.ulg", tmp_path))
    assert small.autopilot == "px4" and len(small.values) > 100
    changes = {d["change"] for d in diff(small.values, appended.values)}
    assert "changed" in changes
    assert diff(small.values, small.values) == []

    def recording(name: str, mode: str) -> Path:
        logger = FlightLogger(tmp_path / name, "D1")
        for i in range(20):
            logger.telemetry("AttitudeActual", 1.8e9 + i * 0.1, {"Roll": float(i)})
        logger.telemetry(
            "ManualControlSettings", 1.8e9, {"Arming": mode, "ChannelMax": {"Throttle": 2000}}
        )
        return logger.close()

    one = read_parameters(store_of(recording("one", "Switch"), tmp_path))
    two = read_parameters(store_of(recording("two", "Always disarmed"), tmp_path))
    assert (one.autopilot, one.source) == ("dronin", "dRonin settings objects")
    assert diff(one.values, two.values) == [
        {
            "name": "ManualControlSettings.Arming",
            "a": "Switch",
            "b": "Always disarmed",
            "change": "changed",
        }
    ]


def test_takeoff_is_where_each_log_armed(tmp_path):
    for path in (px4_ulog(tmp_path / "a.ulg", seconds=15.0), ardupilot_bin(tmp_path / "b.bin")):
        found = takeoff(store_of(path, tmp_path))
        assert found == {"t": pytest.approx(ARM_AT, abs=0.2), "source": "arming"}


@pytest.mark.usefixtures("logs_settings")
def test_parameter_diff_reference_and_refusals_over_the_api(world_tx, tmp_path):
    a = imported(world_tx.org, px4_ulog(tmp_path / "a.ulg", seconds=15.0, parameters=PX4_A))
    b = imported(world_tx.org, px4_ulog(tmp_path / "b.ulg", seconds=15.0, parameters=PX4_B))
    bare = imported(world_tx.org, mavlink_tlog(tmp_path / "bare.tlog"))
    theirs = imported(
        world_tx.other_org, px4_ulog(tmp_path / "c.ulg", seconds=15.0, parameters=PX4_A)
    )
    viewer, operator = client_for(world_tx.viewer), client_for(world_tx.operator)
    base = f"/api/v1/logs/{a.pk}"

    body = viewer.get(f"{base}/parameters/?against={b.pk}").json()
    assert body["differences"] == [
        {"name": "BAT_N_CELLS", "a": 4, "b": None, "change": "only_a"},
        {"name": "COM_RC_LOSS_T", "a": None, "b": 0.5, "change": "only_b"},
        {"name": "MC_ROLL_P", "a": 6.5, "b": 7.0, "change": "changed"},
    ]
    assert body["same"] == 2 and body["a"]["airframe"] == "4001"

    compared = viewer.get(f"{base}/compare/?with={b.pk}").json()
    assert [x["takeoff"]["source"] for x in compared["logs"]] == ["arming", "arming"]
    assert "vehicle_imu_status/accel_vibration_metric" in compared["series"]

    # A reference for PX4 airframe 4001: saved by an operator, then b is judged against it.
    assert viewer.post(f"{base}/reference/").status_code == 403
    assert viewer.get(f"/api/v1/logs/{b.pk}/parameters/?against=reference").status_code == 404
    assert operator.post(f"{base}/reference/").status_code == 201
    against = viewer.get(f"/api/v1/logs/{b.pk}/parameters/?against=reference").json()
    assert against["b"]["kind"] == "reference" and len(against["differences"]) == 3

    # Another organisation's log is not found, either way round.
    assert viewer.get(f"{base}/parameters/?against={theirs.pk}").status_code == 404
    assert viewer.get(f"{base}/compare/?with={theirs.pk}").status_code == 404
    assert client_for(world_tx.outsider).get(f"{base}/parameters/").status_code == 404
    # A log that records no parameters says so.
    plain = viewer.get(f"/api/v1/logs/{bare.pk}/parameters/").json()
    assert plain["count"] == 0 and "records no parameters" in plain["reason"]
    refused = viewer.get(f"{base}/parameters/?against={bare.pk}")
    assert refused.status_code == 409 and "records no parameters" in str(refused.json())
