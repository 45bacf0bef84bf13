"""Generate generated_frames.h from onboard/arming_frames.json, so the firmware, the onboard
agent and the simulator share one definition of the frames.

Usage: python gen_frames_header.py OUTPUT_HEADER [FRAMES_JSON]
"""

from __future__ import annotations

import sys
from pathlib import Path

# Run as a script from the Makefile: import the loader from the repository's onboard package.
sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from onboard.arming_frames import FRAMES_PATH, Frames, load_frames  # noqa: E402


def _array(name: str, values: list[int]) -> str:
    body = ", ".join(str(v) for v in values)
    return f"constexpr uint16_t {name}[kChannelCount] = {{{body}}};"


def render_header(f: Frames) -> str:
    """C++ header text; C++11-compatible because the Arduino AVR core builds with gnu++11."""
    channels = "\n".join(
        f"constexpr uint8_t kCh{name[0].upper()}{name[1:]} = {i};"
        for i, name in enumerate(f.channel_order)
    )
    names = ", ".join(f'"{name}"' for name in f.channel_order)
    lines = [
        "// Generated from onboard/arming_frames.json by gen_frames_header.py. Do not edit; run make.",
        "// Channel values are pulse HIGH times in us (500..1500) after a 500 us LOW separator.",
        "#pragma once",
        "#include <stdint.h>",
        "",
        "namespace frames {",
        "",
        f"constexpr uint8_t kChannelCount = {len(f.channel_order)};",
        channels,
        f"constexpr const char* kChannelNames[kChannelCount] = {{{names}}};",
        "",
        f"constexpr uint16_t kFrameUs = {f.frame_us};",
        f"constexpr uint16_t kSeparatorUs = {f.separator_us};",
        f"constexpr uint16_t kPulseMinUs = {f.pulse_min_us};",
        f"constexpr uint16_t kPulseNeutralUs = {f.pulse_neutral_us};",
        f"constexpr uint16_t kPulseMaxUs = {f.pulse_max_us};",
        f"constexpr uint16_t kSyncMinUs = {f.sync_min_us};",
        "",
        _array("kArmFrameUs", f.arm_frame_us),
        _array("kDisarmFrameUs", f.disarm_frame_us),
        _array("kSafeFrameUs", f.safe_frame_us),
        "",
        f"constexpr uint16_t kSeparatorJitterUs = {f.separator_jitter_us};",
        f"constexpr uint16_t kPulseMarginUs = {f.pulse_margin_us};",
        f"constexpr uint16_t kFramePeriodJitterUs = {f.frame_period_jitter_us};",
        "",
        f"constexpr uint32_t kSignalLossTimeoutUs = {round(f.signal_loss_timeout_s * 1e6)}UL;",
        f"constexpr uint32_t kRequestMaxHoldUs = {round(f.request_max_hold_s * 1e6)}UL;",
        f"constexpr uint32_t kArmingTimeMs = {round(f.arming_time_s * 1e3)}UL;",
        "",
        f"constexpr uint8_t kPinReceiverIn = {f.pins['receiver_in']};",
        f"constexpr uint8_t kPinRequest = {f.pins['request']};",
        f"constexpr uint8_t kPinMode = {f.pins['mode']};",
        f"constexpr uint8_t kPinOutput = {f.pins['output']};",
        "",
        "}  // namespace frames",
        "",
    ]
    return "\n".join(lines)


def main(argv: list[str]) -> int:
    if len(argv) not in (2, 3):
        print(__doc__, file=sys.stderr)
        return 2
    source = Path(argv[2]) if len(argv) == 3 else FRAMES_PATH
    text = render_header(load_frames(source))
    out = Path(argv[1])
    # Rewrite only on change so make does not rebuild everything each run.
    if not out.exists() or out.read_text() != text:
        out.write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
