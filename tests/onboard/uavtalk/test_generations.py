"""The agent tells dRonin firmware generations apart on connect, by the definitions the
board answers, and a board that cannot arm is refused at once with its reason in dRonin's
terms (the real driver against the simulator over a pty)."""

from __future__ import annotations

import shutil
import time
from pathlib import Path

import pytest

from firmware.sim import start_simulator
from onboard.fc.base import FlightControllerError
from onboard.uavtalk import default_objects_dir
from runtime.processes import wait_for

from .test_driver import HOME, SCALE
from .test_receiver_setup import _driver

RELEASE_ID, LATEST_ID = "0x884ed0e6", "0x3c35be0e"


@pytest.mark.parametrize(
    ("firmware", "settings_id"), [("release", 0x884ED0E6), ("latest", 0x3C35BE0E)]
)
def test_the_agent_reads_and_writes_with_the_generation_the_board_answers(firmware, settings_id):
    sim = start_simulator(home=HOME, time_scale=SCALE, firmware=firmware)
    fc = _driver(sim.url)
    try:
        assert wait_for(lambda: fc.arming_switch.settings is not None, 5)
        assert fc.registry.generation == firmware
        assert fc.registry["ManualControlSettings"].id == settings_id
        assert fc.state.setup == ()
        fc.write_object("ManualControlSettings", {"ArmedTimeout": 20000})  # acked, not NACKed
        assert fc.request_object("ManualControlSettings")["ArmedTimeout"] == 20000
    finally:
        fc.stop()
        sim.stop()


def test_the_simulator_refuses_the_other_generations_definition_as_the_board_does():
    sim = start_simulator(home=HOME, time_scale=SCALE, firmware="latest")
    fc = _driver(sim.url)
    try:
        with pytest.raises(FlightControllerError, match="NACK"):
            fc.request_object_id(0x884ED0E6, timeout=2.0)
        fc.request_object_id(0x3C35BE0E, timeout=2.0)
    finally:
        fc.stop()
        sim.stop()


def test_a_board_of_neither_generation_is_reported_with_the_object_and_both_ids(tmp_path: Path):
    objects = tmp_path / "objects"
    shutil.copytree(default_objects_dir(), objects)
    settings = objects / "generations" / "Release-20180729" / "manualcontrolsettings.xml"
    # A later firmware with one more RSSI type: another id than either generation's.
    text = settings.read_text().replace("<option>TBS Crossfire</option>\n      </options>",
                                        "<option>TBS Crossfire</option><option>GHST</option></options>")  # fmt: skip
    settings.write_text(text)
    sim = start_simulator(home=HOME, time_scale=SCALE, extra_args=["--objects-dir", str(objects)])
    fc = _driver(sim.url)
    try:
        assert wait_for(lambda: fc.state.setup, 5)
        (report,) = [item for item in fc.state.setup if "ManualControlSettings" in item]
        assert RELEASE_ID in report and LATEST_ID in report
        assert "Release-20180729" in report and "2021" in report
    finally:
        fc.stop()
        sim.stop()


def test_a_board_with_an_alarm_that_vetoes_arming_is_refused_at_once():
    sim = start_simulator(home=HOME, time_scale=SCALE, extra_args=["--alarm", "Sensors=Critical"])
    fc = _driver(sim.url)
    try:
        assert wait_for(lambda: fc.arming_switch.settings is not None, 5)
        started = time.monotonic()
        with pytest.raises(FlightControllerError, match=r"SystemAlarms.Alarm.Sensors is Critical"):
            fc.arm(timeout=5.0)
        # The board's word, not the 5 s arming timeout: measured 0.7-0.9 ms, quiet or loaded.
        assert time.monotonic() - started < 1.0
        assert not fc.state.armed
    finally:
        fc.stop()
        sim.stop()


def test_a_gps_alarm_does_not_veto_arming_as_in_dronin():
    sim = start_simulator(home=HOME, time_scale=SCALE, extra_args=["--alarm", "GPS=Critical"])
    fc = _driver(sim.url)
    try:
        assert wait_for(lambda: fc.arming_switch.settings is not None, 5)
        fc.arm(timeout=5.0)
        assert fc.state.armed
    finally:
        fc.stop()
        sim.stop()
