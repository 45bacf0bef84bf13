"""The arming-switch emulator firmware: host tests, host tool, generated header, Nano build."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys

import pytest

from onboard.arming_frames import FRAMES_PATH, FramesError, load_frames

from .firmware_tool import FIRMWARE_DIR, emitted_frame, make, pulses_from_segments


def test_the_host_tests_of_the_firmware_logic_all_pass() -> None:
    result = make("test")
    assert result.returncode == 0, result.stdout + result.stderr
    closing = result.stdout.strip().splitlines()[-1]
    match = re.fullmatch(r"(\d+) passed, 0 failed", closing)
    assert match, closing
    assert int(match.group(1)) >= 20


@pytest.mark.parametrize(
    ("command", "field"),
    [("arm", "arm_frame_us"), ("disarm", "disarm_frame_us"), ("safe", "safe_frame_us")],
)
def test_the_firmware_emits_the_frames_defined_in_frames_json(command: str, field: str) -> None:
    frames = load_frames()
    dumped = emitted_frame(command)
    assert dumped["channel_order"] == frames.channel_order
    assert pulses_from_segments(dumped["segments"]) == getattr(frames, field)
    separators = [us for level, us in dumped["segments"] if level == 0]
    assert separators == [frames.separator_us] * (len(frames.channel_order) + 1)
    assert sum(us for _, us in dumped["segments"]) == frames.frame_us == dumped["frame_us"]


def test_the_arm_frame_satisfies_the_flight_controller_arming_thresholds() -> None:
    frames = load_frames()
    arm = pulses_from_segments(emitted_frame("arm")["segments"])
    disarm = pulses_from_segments(emitted_frame("disarm")["segments"])
    throttle, yaw = frames.channel_index("throttle"), frames.channel_index("yaw")
    assert arm[throttle] <= frames.throttle_low_max_us
    assert arm[yaw] >= frames.yaw_arm_min_us
    assert disarm[throttle] <= frames.throttle_low_max_us
    assert disarm[yaw] <= frames.yaw_disarm_max_us
    assert frames.to_channel_period_us(frames.pulse_neutral_us) == 1500


def test_the_generated_header_follows_frames_json(tmp_path) -> None:
    edited = FRAMES_PATH.read_text().replace('"yaw": 1500', '"yaw": 1480')
    source = tmp_path / "frames.json"
    source.write_text(edited)
    header = tmp_path / "generated_frames.h"
    subprocess.run(
        [sys.executable, str(FIRMWARE_DIR / "gen_frames_header.py"), str(header), str(source)],
        check=True,
        timeout=30,
    )
    text = header.read_text()
    assert "kArmFrameUs[kChannelCount] = {1000, 1000, 500, 1480, 1000, 1000};" in text
    assert "constexpr uint32_t kArmingTimeMs = 3000UL;" in text


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        ('"yaw": 1500', '"yaw": 1600', "outside 500..1500"),
        ('"yaw": 1500, ', "", "exactly the channels"),
        ('"sync_min_us": 3000', '"sync_min_us": 9000', "exceed frame_us"),
        ('"separator_us": 500,', "", "missing field"),
    ],
)
def test_a_broken_frames_file_is_refused_with_the_reason(tmp_path, old, new, message) -> None:
    text = FRAMES_PATH.read_text()
    assert old in text
    broken = tmp_path / "frames.json"
    broken.write_text(text.replace(old, new, 1))
    with pytest.raises(FramesError, match=message):
        load_frames(broken)


def test_the_sketch_target_compiles_or_says_it_was_skipped() -> None:
    result = make("sketch")
    assert result.returncode == 0, result.stdout + result.stderr
    if shutil.which("arduino-cli") is None:
        assert "SKIPPED: arduino-cli is not installed" in result.stdout


@pytest.mark.skipif(shutil.which("avr-g++") is None, reason="gcc-avr is not installed")
def test_the_sketch_links_for_the_atmega328p_with_gcc_avr() -> None:
    result = make("avr")
    assert result.returncode == 0, result.stdout + result.stderr
    if "SKIPPED" not in result.stdout:
        used = int(re.search(r"Program:\s+(\d+) bytes", result.stdout).group(1))
        assert 0 < used < 30 * 1024  # the Nano's flash minus the bootloader
