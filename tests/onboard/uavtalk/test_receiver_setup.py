"""A board's receiver set-up for arming through UAVTalkReceiver: checked on connect and
reported as what to change; writes the board does not know are refused at once."""

from __future__ import annotations

import re
import shutil
import time
from pathlib import Path

import pytest

from firmware.sim import start_simulator
from firmware.sim.telemetry import apply_settings
from onboard.arming import UAVTalkReceiverSwitch
from onboard.fc.base import FlightControllerError, VehicleState
from onboard.fc.uavtalk import UAVTalkFlightController
from onboard.heartbeat import build_heartbeat
from onboard.protocol import parse_heartbeat
from onboard.uavtalk import ObjectRegistry, default_objects_dir, receiver_setup
from runtime.processes import wait_for

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


def _driver(url: str, time_scale: float = SCALE, **options) -> UAVTalkFlightController:  # type: ignore[no-untyped-def]
    switch = UAVTalkReceiverSwitch()
    fc = UAVTalkFlightController(url, arming_switch=switch, time_scale=time_scale, **options)
    fc.start()
    assert fc.wait_connected(5)
    return fc


# -- the rules -----------------------------------------------------------------------------

PREFIX = "set ManualControlSettings."
# dRonin's simulation scale with the arming switch on channel 5.
DRONIN_SWITCH = {
    "Arming": "Switch+Throttle",
    "ChannelNumber.Throttle": "1",
    "ChannelNumber.Roll": "2",
    "ChannelNumber.Pitch": "3",
    "ChannelNumber.Yaw": "4",
    "ChannelNumber.Arming": "5",
    **{f"ChannelMin.{e}": "1000" for e in ("Throttle", "Roll", "Pitch", "Yaw", "Arming")},
    **{f"ChannelNeutral.{e}": "5000" for e in ("Roll", "Pitch", "Yaw", "Arming")},
    "ChannelNeutral.Throttle": "1800",
    **{f"ChannelMax.{e}": "9000" for e in ("Throttle", "Roll", "Pitch", "Yaw", "Arming")},
}


def _settings(changes: dict[str, str] | None = None) -> dict:
    return apply_settings(receiver_setup.correct_settings(DEFAULTS), changes or {})


def _switch_args() -> list[str]:
    return [a for k, v in DRONIN_SWITCH.items() for a in ("--receiver-setting", f"{k}={v}")]


def test_a_board_out_of_the_box_is_told_every_setting_to_change():
    found = receiver_setup.problems(DEFAULTS)
    assert f"{PREFIX}Arming to Switch+Throttle (it is Always Disarmed)" in found
    assert f"{PREFIX}ChannelGroups.Throttle to UAVTalk (it is None)" in found
    assert f"{PREFIX}ChannelGroups.Arming to UAVTalk (it is None)" in found
    assert f"{PREFIX}ChannelNumber.Yaw to 4 (it is 0, not a channel 1-8)" in found
    assert any(item.startswith(f"{PREFIX}FlightModeNumber to 1") for item in found)


@pytest.mark.parametrize("option", [*receiver_setup.SWITCH_OPTIONS, *receiver_setup.GESTURES])
def test_every_arming_option_that_can_arm_is_accepted(option):
    assert receiver_setup.problems(_settings({"Arming": option})) == []


def test_dronins_simulation_scale_with_an_arming_switch_is_accepted():
    assert receiver_setup.problems(_settings(DRONIN_SWITCH)) == []


def test_a_gesture_board_does_not_need_an_arming_channel():
    settings = _settings({"ChannelGroups.Arming": "None", "ChannelNumber.Arming": "0"})
    assert receiver_setup.problems(settings) == []


@pytest.mark.parametrize(
    ("changes", "expected"),
    [
        ({"Arming": "Always Disarmed"}, "Arming to Switch+Throttle (it is Always Disarmed)"),
        (
            {**DRONIN_SWITCH, "ChannelGroups.Arming": "PPM"},
            "ChannelGroups.Arming to UAVTalk (it is PPM)",
        ),
        ({"ChannelGroups.Pitch": "PPM"}, "ChannelGroups.Pitch to UAVTalk (it is PPM)"),
        (
            {**DRONIN_SWITCH, "ChannelNumber.Arming": "4"},
            "ChannelNumber.Arming to 5 (it is 4, the channel of Yaw)",
        ),
        ({"ChannelNumber.Roll": "9"}, "ChannelNumber.Roll to 2 (it is 9, not a channel 1-8)"),
        (
            {**DRONIN_SWITCH, "ChannelMax.Arming": "1000"},
            "ChannelMax.Arming to 2000 (it is 1000, the same as ChannelMin.Arming)",
        ),
        (
            {"ChannelNeutral.Yaw": "2000"},
            "ChannelNeutral.Yaw to 1500 (it is 2000, not between ChannelMin.Yaw 1000 and "
            "ChannelMax.Yaw 2000)",
        ),
        (
            {"ChannelNeutral.Throttle": "900"},
            "ChannelNeutral.Throttle to 1500 (it is 900, not between ChannelMin.Throttle 1000 "
            "and ChannelMax.Throttle 2000)",
        ),
    ],
)
def test_a_setting_that_breaks_arming_is_named_with_what_to_set(changes, expected):
    assert receiver_setup.problems(_settings(changes)) == [PREFIX + expected]


def test_the_switch_is_written_in_the_boards_scale_and_channel_numbers():
    settings = _settings(DRONIN_SWITCH)
    # throttle, roll, pitch, yaw, arming; the unused channels at a neutral, never 65535
    assert (
        receiver_setup.channel_values(settings, "arm")
        == [1000, 5000, 5000, 5000, 9000] + [5000] * 3
    )
    assert receiver_setup.channel_values(settings, "disarm")[4] == 1000
    assert receiver_setup.channel_values(settings, "safe")[4] == 1000


@pytest.mark.parametrize("option", [*receiver_setup.SWITCH_OPTIONS, *receiver_setup.GESTURES])
def test_what_the_agent_writes_reads_on_the_board_as_meant(option):
    settings = _settings({**DRONIN_SWITCH, "Arming": option})
    for mode in ("arm", "disarm"):
        assert receiver_setup.gesture(settings, receiver_setup.channel_values(settings, mode)) == (
            mode
        )
    safe = receiver_setup.gesture(settings, receiver_setup.channel_values(settings, "safe"))
    assert safe == ("disarm" if option in receiver_setup.SWITCH_OPTIONS else None)


def test_yaw_left_arms_with_the_yaw_at_its_minimum():
    settings = _settings({"Arming": "Yaw Left+Throttle"})
    assert receiver_setup.channel_values(settings, "arm")[:4] == [1500, 1500, 1000, 1000]
    assert receiver_setup.channel_values(settings, "disarm")[3] == 2000


def test_a_channel_with_no_data_arms_nothing():
    settings = _settings(DRONIN_SWITCH)
    channels = receiver_setup.channel_values(settings, "arm")
    channels[4] = receiver_setup.NO_DATA
    assert receiver_setup.read(settings, channels) is None
    assert receiver_setup.gesture(settings, channels) is None


def test_the_switch_falls_back_to_the_fixed_frames_when_the_settings_cannot_arm():
    switch = UAVTalkReceiverSwitch()
    fixed = switch.channels("arm")
    assert fixed[:4] == [1500, 1500, 1000, 2000]
    switch.configure(_settings({"Arming": "Always Disarmed"}))
    assert switch.settings is None and switch.channels("arm") == fixed
    switch.configure(_settings({**DRONIN_SWITCH, "Arming": "Roll Left+Throttle"}))
    assert switch.channels("arm")[:5] == [1000, 1000, 5000, 5000, 5000]
    assert switch.channels("disarm")[:5] == [1000, 9000, 5000, 5000, 5000]


class _Board:
    """Stands in for the driver: its FlightStatus, and the channels written to it."""

    def __init__(self) -> None:
        self.state = VehicleState(armed=True)
        self.writes: list[list[int]] = []

    def write_object(self, name: str, fields: dict, **options) -> None:  # type: ignore[no-untyped-def]
        self.writes.append(list(fields["Channel"]))


def test_released_while_armed_the_switch_keeps_the_rest_position_coming_until_disarmed():
    board = _Board()
    switch = UAVTalkReceiverSwitch(board, rate_hz=100.0)
    switch.configure(_settings(DRONIN_SWITCH))
    switch.request_arm()
    switch.release()  # armed: a board whose channels stop hands control to Failsafe
    count = len(board.writes)
    assert wait_for(lambda: len(board.writes) > count + 10, 2)
    assert board.writes[-1][:5] == [1000, 5000, 5000, 5000, 9000]  # switch stays high
    board.state = VehicleState(armed=False)
    time.sleep(0.1)
    count = len(board.writes)
    time.sleep(0.2)
    assert len(board.writes) == count  # disarmed at rest: nothing more to hold
    switch.close()


# -- the agent and the simulated board -----------------------------------------------------------


def _armed_and_disarmed(fc: UAVTalkFlightController) -> None:
    fc.arm(timeout=5)
    assert fc.state.armed
    time.sleep(0.5)  # released: the board stays armed
    assert fc.state.armed
    fc.disarm(timeout=5)
    assert not fc.state.armed


def test_a_board_set_up_for_yaw_right_is_reported_so_and_armed_and_disarmed():
    sim = start_simulator(home=HOME, time_scale=SCALE)
    fc = _driver(sim.url)
    try:
        assert fc.check_receiver_setup() == ()
        assert fc.state.setup == ()
        assert fc.arming_switch.settings["Arming"] == "Yaw Right+Throttle"
        _armed_and_disarmed(fc)
    finally:
        fc.stop()
        sim.stop()


def test_a_board_with_an_arming_switch_in_dronins_scale_is_armed_and_disarmed():
    sim = start_simulator(home=HOME, time_scale=SCALE, extra_args=_switch_args())
    fc = _driver(sim.url)
    try:
        assert fc.check_receiver_setup() == ()
        switch = fc.arming_switch
        assert switch.settings["Arming"] == "Switch+Throttle"
        assert switch.channels("arm")[:5] == [1000, 5000, 5000, 5000, 9000]
        _armed_and_disarmed(fc)
    finally:
        fc.stop()
        sim.stop()


def _hold_until(fc: UAVTalkFlightController, channels: list[int], seen, seconds: float) -> bool:  # type: ignore[no-untyped-def]
    """Stream `channels` until `seen()`, as a transmitter does: the board counts values
    older than half a second as gone, so one write read by a board that stalled for that
    long would count as a safe frame."""
    until = time.monotonic() + seconds
    while time.monotonic() < until:
        fc.write_object("UAVTalkReceiver", {"Channel": channels, "RSSI": 65535}, acked=False)
        if seen():
            return True
        time.sleep(0.04)
    return seen()


def _hold(fc: UAVTalkFlightController, channels: list[int], seconds: float) -> None:
    _hold_until(fc, channels, lambda: False, seconds)


def test_after_a_cancelled_attempt_the_switch_must_go_low_and_the_agent_does_so():
    # In real time: the attempt must be seen and cancelled within ArmTime (1 s, the
    # default), which at the other tests' time scale is 50 ms of the wall's, too short
    # for a loaded machine.
    sim = start_simulator(home=HOME, time_scale=1.0, extra_args=_switch_args())
    fc = _driver(sim.url, time_scale=1.0)
    try:
        assert wait_for(lambda: fc.arming_switch.settings is not None, 5)
        arm = fc.arming_switch.channels("arm")
        assert _hold_until(fc, arm, lambda: fc.state.arming, 2)
        # Throttle up: the attempt is cancelled.
        assert _hold_until(fc, [9000, *arm[1:]], lambda: not fc.state.arming, 2)
        _hold(fc, arm, 1.5)  # longer than ArmTime, the switch never low: no arming
        assert not fc.state.armed and not fc.state.arming
        fc.arm(timeout=5)  # the agent drops the switch first, then arms
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
        # It could not arm from these channels: the agent says why at once.
        started = time.monotonic()
        with pytest.raises(FlightControllerError, match=re.escape(f"will not arm: {wanted}")):
            fc.arm(timeout=5.0)
        # Not the 5 s timeout: measured 0.6-0.7 ms, quiet or loaded.
        assert time.monotonic() - started < 1.0
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
        # The NACK, not the 5 s timeout: measured 0.7-1.5 ms, quiet or loaded.
        assert time.monotonic() - started < 1.0
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
        ("set ManualControlSettings.Arming to Switch+Throttle (it is Always Disarmed)",)
    )
    Drone.objects.filter(drone_id="ACME_1").update(fc=fc_state(state, _now()))
    client = Client()
    client.force_login(world.viewer)
    html = client.get("/drones/ACME_1/").content.decode()
    assert "needs setting up before the drone can arm" in html
    assert "set ManualControlSettings.Arming to Switch+Throttle (it is Always Disarmed)" in html


def _heartbeat_state(setup: tuple[str, ...]):  # type: ignore[no-untyped-def]
    from onboard.fc.base import VehicleState

    state = VehicleState(connected=True, setup=setup)
    return parse_heartbeat(build_heartbeat("ACME_1", state, None).to_dict())


def _now():  # type: ignore[no-untyped-def]
    from django.utils import timezone

    return timezone.now()
