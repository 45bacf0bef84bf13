#include "ppm.h"

namespace ppm {

static_assert(kChannelCount * (frames::kSeparatorUs + frames::kPulseMaxUs) + frames::kSeparatorUs +
                      frames::kSyncMinUs <=
                  frames::kFrameUs,
              "the longest frame plus the sync gap must fit in kFrameUs");

namespace {

Frame frameFrom(const uint16_t* values) {
  Frame f;
  for (uint8_t i = 0; i < kChannelCount; ++i) f.pulse_us[i] = values[i];
  return f;
}

uint16_t clampPulse(uint32_t us) {
  if (us < frames::kPulseMinUs) return frames::kPulseMinUs;
  if (us > frames::kPulseMaxUs) return frames::kPulseMaxUs;
  return static_cast<uint16_t>(us);
}

uint32_t absDiff(uint32_t a, uint32_t b) { return a > b ? a - b : b - a; }

// Durations longer than uint16_t (a line idle for seconds) saturate: still out of range.
uint16_t saturate16(uint32_t us) { return us > 0xFFFFu ? 0xFFFFu : static_cast<uint16_t>(us); }

}  // namespace

bool operator==(const Frame& a, const Frame& b) {
  for (uint8_t i = 0; i < kChannelCount; ++i) {
    if (a.pulse_us[i] != b.pulse_us[i]) return false;
  }
  return true;
}

Frame armFrame() { return frameFrom(frames::kArmFrameUs); }
Frame disarmFrame() { return frameFrom(frames::kDisarmFrameUs); }
Frame safeFrame() { return frameFrom(frames::kSafeFrameUs); }

const char* verdictName(Verdict v) {
  switch (v) {
    case Verdict::Ok: return "ok";
    case Verdict::TooFewChannels: return "too few channels";
    case Verdict::TooManyChannels: return "too many channels";
    case Verdict::PulseOutOfRange: return "pulse out of range";
    case Verdict::SeparatorJitter: return "separator jitter";
    case Verdict::PeriodJitter: return "frame period jitter";
  }
  return "?";
}

Verdict validate(const RawFrame& raw, Frame& out) {
  if (raw.overflow || raw.pulses > kChannelCount) return Verdict::TooManyChannels;
  if (raw.pulses < kChannelCount) return Verdict::TooFewChannels;
  const uint16_t lo = frames::kPulseMinUs - frames::kPulseMarginUs;
  const uint16_t hi = frames::kPulseMaxUs + frames::kPulseMarginUs;
  for (uint8_t i = 0; i < raw.pulses; ++i) {
    if (raw.pulse_us[i] < lo || raw.pulse_us[i] > hi) return Verdict::PulseOutOfRange;
  }
  // Every channel is preceded by a separator and one more closes the frame.
  if (raw.separators != raw.pulses + 1) return Verdict::SeparatorJitter;
  for (uint8_t i = 0; i < raw.separators; ++i) {
    if (absDiff(raw.separator_us[i], frames::kSeparatorUs) > frames::kSeparatorJitterUs) {
      return Verdict::SeparatorJitter;
    }
  }
  if (absDiff(raw.period_us, frames::kFrameUs) > frames::kFramePeriodJitterUs) {
    return Verdict::PeriodJitter;
  }
  for (uint8_t i = 0; i < kChannelCount; ++i) out.pulse_us[i] = clampPulse(raw.pulse_us[i]);
  return Verdict::Ok;
}

Decoder::Decoder() {
  for (uint8_t i = 0; i < kVerdictCount; ++i) stats_.verdicts[i] = 0;
  stats_.missed_edges = 0;
  latest_ = safeFrame();
  last_edge_us_ = 0;
  frame_start_us_ = 0;
  last_verdict_ = Verdict::Ok;
  have_edge_ = false;
  level_high_ = true;
  fresh_ = false;
  reset();
}

void Decoder::reset() {
  in_frame_ = false;
  raw_.pulses = 0;
  raw_.separators = 0;
  raw_.overflow = false;
  raw_.period_us = 0;
}

void Decoder::startFrame(uint32_t t_us) {
  reset();
  in_frame_ = true;
  frame_start_us_ = t_us;
}

void Decoder::finishFrame(uint32_t t_us) {
  raw_.period_us = t_us - frame_start_us_;
  Frame decoded;
  last_verdict_ = validate(raw_, decoded);
  ++stats_.verdicts[static_cast<uint8_t>(last_verdict_)];
  if (last_verdict_ == Verdict::Ok) {
    latest_ = decoded;
    fresh_ = true;
  }
}

void Decoder::onEdge(bool level_high, uint32_t t_us) {
  if (!have_edge_) {
    have_edge_ = true;
    level_high_ = level_high;
    last_edge_us_ = t_us;
    return;
  }
  const uint32_t held_us = t_us - last_edge_us_;
  const bool was_high = level_high_;
  level_high_ = level_high;
  last_edge_us_ = t_us;
  if (was_high == level_high) {
    // The pin read the same level twice: a spike too short to see. Nothing in this frame
    // can be trusted any more.
    ++stats_.missed_edges;
    reset();
    return;
  }
  if (level_high) {
    // Rising edge: a LOW separator just ended.
    if (in_frame_ && raw_.separators < kMaxCaptured + 1) {
      raw_.separator_us[raw_.separators++] = saturate16(held_us);
    }
    return;
  }
  // Falling edge: a HIGH stretch (channel pulse or sync gap) just ended.
  if (held_us >= frames::kSyncMinUs) {
    if (in_frame_) finishFrame(t_us);
    startFrame(t_us);
    return;
  }
  if (!in_frame_) return;
  if (raw_.pulses < kMaxCaptured) {
    raw_.pulse_us[raw_.pulses++] = saturate16(held_us);
  } else {
    raw_.overflow = true;
  }
}

bool Decoder::takeFrame(Frame& out) {
  if (!fresh_) return false;
  out = latest_;
  fresh_ = false;
  return true;
}

void buildPulseTrain(const Frame& frame, PulseTrain& out) {
  uint32_t used = 0;
  uint8_t n = 0;
  for (uint8_t i = 0; i < kChannelCount; ++i) {
    const uint16_t pulse = clampPulse(frame.pulse_us[i]);
    out.seg[n++] = Segment{false, frames::kSeparatorUs};
    out.seg[n++] = Segment{true, pulse};
    used += frames::kSeparatorUs + pulse;
  }
  out.seg[n++] = Segment{false, frames::kSeparatorUs};
  used += frames::kSeparatorUs;
  // onboard/arming_frames.py checks that the longest frame plus sync_min_us fits in frame_us.
  out.seg[n] = Segment{true, static_cast<uint16_t>(frames::kFrameUs - used)};
}

}  // namespace ppm
