"""A board's receiver set-up for arming through UAVTalkReceiver: checked on connect and
reported as what to change; writes the board does not know are refused at once."""

from __future__ import annotations

import shutil
import time
from pathlib import Path

import pytest

from firmware.sim import start_simulator
from onboard.arming import UAVTalkReceiverSwitch
from onboard.fc.base import FlightControllerError
from onboard.fc.uavtalk import UAVTalkFlightController
from onboard.heartbeat import build_heartbeat
from onboard.processes import wait_for
from onboard.protocol import parse_heartbeat
from onboard.uavtalk import ObjectRegistry, default_objects_dir, receiver_setup

from .test_driver import HOME, SCALE

REGISTRY = ObjectRegistry.load()
DEFAULTS = REGISTRY["ManualControlSettings"].defaults()
# The receiver object as it was before dRonin added RSSI: a board of the release does not
# know its id.
OLD_RECEIVER = """<xml>
  <object name="UAVTalkReceiver" settings="false" singleinstance="true">
    <description>Receiver channels over the telemetry link, without RSSI.</description>
    <access gcs="readwrite" flight="readwrite"/>
    <logging updatemode="manual" period="0"/>
    <telemetrygcs acked="false" updatemode="onchange" period="0"/>
    <telemetryflight acked="false" updatemode="onchange" period="0"/>
    <field name="Channel" units="us" type="uint16" elements="8" defaultvalue="0"/>
  </object>
</xml>
"""


def _driver(url: str, **options) -> UAVTalkFlightController:  # type: ignore[no-untyped-def]
    switch = UAVTalkReceiverSwitch()
    fc = UAVTalkFlightController(url, arming_switch=switch, time_scale=SCALE, **options)
    fc.start()
    assert fc.wait_connected(5)
    return fc


# -- the rules -----------------------------------------------------------------------------


def test_a_board_out_of_the_box_is_told_every_setting_to_change():
    found = receiver_setup.problems(DEFAULTS)
    assert "set ManualControlSettings.ChannelGroups.Throttle to UAVTalk (it is None)" in found
    assert "set ManualControlSettings.ChannelNumber.Yaw to 4 (it is 0)" in found
    assert "set ManualControlSettings.Arming to Yaw Right+Throttle (it is Always Disarmed)" in found
    assert any(item.startswith("set ManualControlSettings.FlightModeNumber to 1") for item in found)


def test_the_required_settings_leave_nothing_to_change():
    assert receiver_setup.problems(receiver_setup.correct_settings(DEFAULTS)) == []


@pytest.mark.parametrize(
    ("field", "element", "value", "expected"),
    [
        ("ChannelNeutral", "Throttle", 900, "ChannelNeutral.Throttle to 1500 (it is 900)"),
        ("ChannelMax", "Yaw", 3000, "ChannelMax.Yaw to 2000 (it is 3000)"),
        ("ChannelGroups", "Pitch", "PPM", "ChannelGroups.Pitch to UAVTalk (it is PPM)"),
        ("ChannelNumber", "Roll", 5, "ChannelNumber.Roll to 2 (it is 5)"),
    ],
)
def test_a_setting_that_breaks_arming_is_named_with_its_value(field, element, value, expected):
    settings = receiver_setup.correct_settings(DEFAULTS)
    settings[field][receiver_setup.ELEMENTS.index(element)] = value
    assert receiver_setup.problems(settings) == [f"set ManualControlSettings.{expected}"]


def test_a_scale_that_still_reads_the_sticks_right_is_accepted():
    settings = receiver_setup.correct_settings(DEFAULTS)
    # A wider throttle range with its neutral still above the low value sent.
    settings["ChannelMin"][0], settings["ChannelNeutral"][0] = 950, 1100
    assert receiver_setup.problems(settings) == []


# -- the agent and the simulated board -----------------------------------------------------------


def test_a_board_set_up_right_is_reported_so_and_arms_through_the_receiver():
    sim = start_simulator(home=HOME, time_scale=SCALE)
    fc = _driver(sim.url)
    try:
        assert fc.check_receiver_setup() == ()
        assert fc.state.setup == ()
        fc.arm(timeout=5)
        assert fc.state.armed
    finally:
        fc.stop()
        sim.stop()


def test_a_board_set_up_wrong_is_reported_on_connect_and_in_the_heartbeat():
    sim = start_simulator(
        home=HOME,
        time_scale=SCALE,
        extra_args=["--receiver-setting", "ChannelGroups.Throttle=PWM"],
    )
    fc = _driver(sim.url)
    try:
        wanted = "set ManualControlSettings.ChannelGroups.Throttle to UAVTalk (it is PWM)"
        assert wait_for(lambda: fc.state.setup == (wanted,), 5), fc.state.setup
        heartbeat = parse_heartbeat(build_heartbeat("DRONE_1", fc.state, None).to_dict())
        assert heartbeat.fc_setup == (wanted,)
        # As a real board would, it ignores the channels: arming cannot happen.
        with pytest.raises(FlightControllerError, match="did not arm"):
            fc.arm(timeout=1.0)
        assert not fc.state.armed
    finally:
        fc.stop()
        sim.stop()


def test_a_write_the_board_does_not_know_is_refused_at_once(tmp_path: Path):
    objects = tmp_path / "objects"
    shutil.copytree(default_objects_dir(), objects)
    (objects / "uavtalkreceiver.xml").write_text(OLD_RECEIVER)
    sim = start_simulator(home=HOME, time_scale=SCALE)
    fc = _driver(sim.url, objects_dir=objects)
    try:
        started = time.monotonic()
        with pytest.raises(FlightControllerError, match="does not know UAVTalkReceiver") as caught:
            fc.write_object("UAVTalkReceiver", {"Channel": [1500] * 8}, timeout=5.0)
        assert time.monotonic() - started < 1.0  # the NACK, not the 5 s timeout
        assert "0xe9dad5f4" in str(caught.value)
        found = fc.check_receiver_setup()
        assert any("does not know UAVTalkReceiver" in item for item in found)
    finally:
        fc.stop()
        sim.stop()


def test_the_drone_page_lists_what_to_change_on_its_board(world):
    from django.test import Client

    from fleet.heartbeats import fc_state
    from fleet.models import Drone

    state = _heartbeat_state(
        ("set ManualControlSettings.Arming to Yaw Right+Throttle (it is Switch)",)
    )
    Drone.objects.filter(drone_id="ACME_1").update(fc=fc_state(state, _now()))
    client = Client()
    client.force_login(world.viewer)
    html = client.get("/drones/ACME_1/").content.decode()
    assert "needs setting up before the drone can arm" in html
    assert "set ManualControlSettings.Arming to Yaw Right+Throttle (it is Switch)" in html


def _heartbeat_state(setup: tuple[str, ...]):  # type: ignore[no-untyped-def]
    from onboard.fc.base import VehicleState

    state = VehicleState(connected=True, setup=setup)
    return parse_heartbeat(build_heartbeat("ACME_1", state, None).to_dict())


def _now():  # type: ignore[no-untyped-def]
    from django.utils import timezone

    return timezone.now()
