"""Build and run the arming-switch host tools from tests."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

FIRMWARE_DIR = Path(__file__).resolve().parents[2] / "firmware" / "arming_switch"


def make(target: str) -> subprocess.CompletedProcess[str]:
    """Run a target of the firmware Makefile; output is captured for assertions."""
    return subprocess.run(
        ["make", "--no-print-directory", "-C", str(FIRMWARE_DIR), target],
        capture_output=True,
        text=True,
        timeout=300,
    )


def emitted_frame(command: str) -> dict:
    """What the firmware puts on its output line for `command` (arm, disarm or safe)."""
    built = make("tools")
    assert built.returncode == 0, built.stdout + built.stderr
    out = subprocess.run(
        [str(FIRMWARE_DIR / "build" / "frame_dump"), command],
        capture_output=True,
        text=True,
        check=True,
        timeout=30,
    )
    return json.loads(out.stdout)


def pulses_from_segments(segments: list[list[int]]) -> list[int]:
    """Channel pulse widths from one output frame: every HIGH stretch except the sync gap."""
    highs = [us for level, us in segments if level == 1]
    return highs[:-1]
