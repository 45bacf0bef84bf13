// Prints, as one JSON line, the frame the firmware puts on its output line for a command,
// by running the real emulator logic with the request pins set accordingly.
// Usage: frame_dump arm|disarm|safe
#include <cstring>
#include <iostream>

#include "../arming.h"

namespace {

int usage() {
  std::cerr << "usage: frame_dump arm|disarm|safe\n";
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) return usage();
  arming::RequestPins pins{false, false};
  if (std::strcmp(argv[1], "arm") == 0) {
    pins = arming::RequestPins{true, false};
  } else if (std::strcmp(argv[1], "disarm") == 0) {
    pins = arming::RequestPins{true, true};
  } else if (std::strcmp(argv[1], "safe") != 0) {
    return usage();
  }
  // No receiver is attached, so "safe" is what signal loss produces. Skip the first frame
  // and print the second, i.e. a frame from steady state.
  arming::Emulator emu;
  uint32_t now = 0;
  for (uint8_t i = 0; i < ppm::kSegmentsPerFrame; ++i) now += emu.nextOutputSegment(pins, now).us;
  std::cout << "{\"command\": \"" << argv[1] << "\", \"mode\": \"" << arming::modeName(emu.mode())
            << "\", \"channel_order\": [";
  for (uint8_t i = 0; i < frames::kChannelCount; ++i) {
    std::cout << (i ? ", " : "") << "\"" << frames::kChannelNames[i] << "\"";
  }
  std::cout << "], \"segments\": [";
  uint32_t total = 0;
  for (uint8_t i = 0; i < ppm::kSegmentsPerFrame; ++i) {
    const ppm::Segment s = emu.nextOutputSegment(pins, now);
    now += s.us;
    total += s.us;
    std::cout << (i ? ", " : "") << "[" << (s.high ? 1 : 0) << ", " << s.us << "]";
  }
  std::cout << "], \"frame_us\": " << total << "}\n";
  return 0;
}
