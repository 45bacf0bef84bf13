"""Loader for arming_frames.json, the one definition of the arming-switch PPM frames.

The JSON ships as package data: the agent reads it at run time, the simulator and the
firmware header generator (firmware/arming_switch) read the same file. Channel values are pulse HIGH times in microseconds (500..1500); add
``separator_us`` to get the usual 1000..2000 us channel period (see ``to_channel_period_us``).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from importlib.resources import files
from pathlib import Path

FRAMES_PATH = Path(str(files(__package__).joinpath("arming_frames.json")))


class FramesError(ValueError):
    """arming_frames.json is missing a field or describes frames that cannot be sent."""


@dataclass(frozen=True)
class Frames:
    channel_order: list[str]
    frame_us: int
    separator_us: int
    pulse_min_us: int
    pulse_neutral_us: int
    pulse_max_us: int
    sync_min_us: int
    arm_frame_us: list[int]
    disarm_frame_us: list[int]
    safe_frame_us: list[int]
    separator_jitter_us: int
    pulse_margin_us: int
    frame_period_jitter_us: int
    signal_loss_timeout_s: float
    request_max_hold_s: float
    arming_time_s: float
    disarming_time_s: float
    throttle_low_max_us: int
    yaw_arm_min_us: int
    yaw_disarm_max_us: int
    pins: dict[str, int]

    def channel_index(self, name: str) -> int:
        """Position of a channel (``"throttle"``, ``"yaw"``...) in a frame."""
        return self.channel_order.index(name)

    def to_channel_period_us(self, pulse_us: int) -> int:
        """Pulse HIGH time -> the usual RC channel period (separator + pulse)."""
        return pulse_us + self.separator_us


def _channels(raw: dict, name: str, order: list[str], lo: int, hi: int) -> list[int]:
    frame = raw["frames"][name]
    missing = [c for c in order if c not in frame]
    if missing or len(frame) != len(order):
        raise FramesError(
            f"frame {name!r} must name exactly the channels {order}, got {sorted(frame)}"
        )
    values = [int(frame[c]) for c in order]
    for channel, value in zip(order, values, strict=True):
        if not lo <= value <= hi:
            raise FramesError(f"frame {name!r} channel {channel!r}={value} outside {lo}..{hi} us")
    return values


def load_frames(path: Path | str = FRAMES_PATH) -> Frames:
    """Read and check arming_frames.json; raise FramesError with the offending field."""
    raw = json.loads(Path(path).read_text())
    try:
        order = list(raw["channel_order"])
        pulse = raw["pulse_us"]
        lo, hi = int(pulse["min"]), int(pulse["max"])
        tol, timings, fc = raw["tolerances"], raw["timings"], raw["flight_controller"]
        frames = Frames(
            channel_order=order,
            frame_us=int(raw["frame_us"]),
            separator_us=int(raw["separator_us"]),
            pulse_min_us=lo,
            pulse_neutral_us=int(pulse["neutral"]),
            pulse_max_us=hi,
            sync_min_us=int(raw["sync_min_us"]),
            arm_frame_us=_channels(raw, "arm", order, lo, hi),
            disarm_frame_us=_channels(raw, "disarm", order, lo, hi),
            safe_frame_us=_channels(raw, "safe", order, lo, hi),
            separator_jitter_us=int(tol["separator_jitter_us"]),
            pulse_margin_us=int(tol["pulse_margin_us"]),
            frame_period_jitter_us=int(tol["frame_period_jitter_us"]),
            signal_loss_timeout_s=int(timings["signal_loss_timeout_ms"]) / 1000.0,
            request_max_hold_s=int(timings["request_max_hold_ms"]) / 1000.0,
            arming_time_s=float(fc["arming_time_s"]),
            disarming_time_s=float(fc["disarming_time_s"]),
            throttle_low_max_us=int(fc["throttle_low_max_us"]),
            yaw_arm_min_us=int(fc["yaw_arm_min_us"]),
            yaw_disarm_max_us=int(fc["yaw_disarm_max_us"]),
            pins={k: int(v) for k, v in raw["pins"].items() if not k.startswith("_")},
        )
    except KeyError as exc:
        raise FramesError(f"{path}: missing field {exc}") from exc
    _check_fits(frames)
    return frames


def _check_fits(f: Frames) -> None:
    """The longest frame plus the sync gap must fit in frame_us, or the decoder cannot sync."""
    if not f.pulse_min_us < f.pulse_neutral_us < f.pulse_max_us:
        raise FramesError("pulse_us must satisfy min < neutral < max")
    longest = len(f.channel_order) * (f.separator_us + f.pulse_max_us) + f.separator_us
    if longest + f.sync_min_us > f.frame_us:
        raise FramesError(f"{longest} us of channels + sync_min_us {f.sync_min_us} exceed frame_us")
    if f.sync_min_us <= f.pulse_max_us + f.pulse_margin_us:
        raise FramesError("sync_min_us must be longer than the longest accepted pulse")
