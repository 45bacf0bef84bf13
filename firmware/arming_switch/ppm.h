// PPM frame logic for the arming-switch emulator: decode, validate, build pulse trains.
// Plain C++ (C++11 subset, no Arduino headers, no libstdc++) so the same file builds for the
// ATmega328P and for the host tests. Times are microseconds in uint32_t that may wrap;
// only differences are used, so wrap-around is harmless.
#pragma once

#include <stddef.h>
#include <stdint.h>

#include "generated_frames.h"

namespace ppm {

using frames::kChannelCount;

// One frame of channel values: pulse HIGH times in us, in onboard/arming_frames.json channel order.
struct Frame {
  uint16_t pulse_us[kChannelCount];
};

bool operator==(const Frame& a, const Frame& b);
inline bool operator!=(const Frame& a, const Frame& b) { return !(a == b); }

Frame armFrame();
Frame disarmFrame();
Frame safeFrame();

// Timings of one received frame exactly as captured, before validation. Room for a few
// more channels than expected so "too many channels" is seen as such.
constexpr uint8_t kMaxCaptured = kChannelCount + 2;

struct RawFrame {
  uint16_t pulse_us[kMaxCaptured];
  uint16_t separator_us[kMaxCaptured + 1];
  uint8_t pulses;
  uint8_t separators;
  bool overflow;       // more pulses than kMaxCaptured arrived
  uint32_t period_us;  // from the end of the previous sync to the end of this frame's sync
};

enum class Verdict : uint8_t {
  Ok = 0,
  TooFewChannels,
  TooManyChannels,
  PulseOutOfRange,
  SeparatorJitter,
  PeriodJitter,
};
constexpr uint8_t kVerdictCount = 6;

const char* verdictName(Verdict v);

// Check a captured frame against onboard/arming_frames.json (channel count, pulse range, separator and
// period jitter). On Ok, `out` holds the pulses clamped to [kPulseMinUs, kPulseMaxUs].
Verdict validate(const RawFrame& raw, Frame& out);

struct DecoderStats {
  uint32_t verdicts[kVerdictCount];  // frames seen, by verdict (index 0 = accepted)
  uint32_t missed_edges;             // two edges with the same level: a glitch was too short
};

// Turns line edges of the receiver's inverted PPM (idle high, 500 us LOW separators, channel
// = HIGH time, long HIGH sync) into validated frames. Call onEdge from the pin interrupt.
class Decoder {
 public:
  Decoder();
  // `level_high` is the line level after the edge, `t_us` the edge time.
  void onEdge(bool level_high, uint32_t t_us);
  // True once per newly accepted frame, copied into `out`.
  bool takeFrame(Frame& out);
  // Forget any partial frame and wait for the next sync gap.
  void reset();
  const DecoderStats& stats() const { return stats_; }
  Verdict lastVerdict() const { return last_verdict_; }

 private:
  void startFrame(uint32_t t_us);
  void finishFrame(uint32_t t_us);

  RawFrame raw_;
  Frame latest_;
  DecoderStats stats_;
  uint32_t last_edge_us_;
  uint32_t frame_start_us_;
  Verdict last_verdict_;
  bool have_edge_;
  bool level_high_;
  bool in_frame_;
  bool fresh_;
};

// One constant-level stretch of the output line.
struct Segment {
  bool high;
  uint16_t us;
};

// LOW separator + HIGH pulse per channel, a closing LOW separator, then HIGH sync.
constexpr uint8_t kSegmentsPerFrame = 2 * kChannelCount + 2;

struct PulseTrain {
  Segment seg[kSegmentsPerFrame];
};

// Exact output timings of a frame; channel values are clamped into range first and the
// sync fills the frame to exactly kFrameUs.
void buildPulseTrain(const Frame& frame, PulseTrain& out);

}  // namespace ppm
