// Virtual-time test bench: a receiver line made of segments, and the emulator's two
// interrupts interleaved in time order exactly as on the Nano.
#pragma once

#include <functional>
#include <vector>

#include "../arming.h"
#include "../ppm.h"

namespace line {

struct Edge {
  bool high;
  uint32_t t_us;
};

inline ppm::Frame frameOf(uint16_t a, uint16_t b, uint16_t c, uint16_t d, uint16_t e,
                          uint16_t f) {
  return ppm::Frame{{a, b, c, d, e, f}};
}

inline std::vector<ppm::Segment> segmentsOf(const ppm::Frame& frame) {
  ppm::PulseTrain train;
  ppm::buildPulseTrain(frame, train);
  return std::vector<ppm::Segment>(train.seg, train.seg + ppm::kSegmentsPerFrame);
}

inline std::vector<ppm::Segment> repeat(const std::vector<ppm::Segment>& segs, int times) {
  std::vector<ppm::Segment> out;
  for (int i = 0; i < times; ++i) out.insert(out.end(), segs.begin(), segs.end());
  return out;
}

// Edges of a line that was at `level_before` until `start_us`; equal-level neighbours merge.
// By default the line was low, so the first segment starts with an edge the decoder sees.
inline std::vector<Edge> edgesOf(const std::vector<ppm::Segment>& segs, uint32_t start_us,
                                 bool level_before = false) {
  std::vector<Edge> edges;
  bool level = level_before;
  uint32_t t = start_us;
  for (const ppm::Segment& s : segs) {
    if (s.high != level) edges.push_back(Edge{s.high, t});
    level = s.high;
    t += s.us;
  }
  return edges;
}

inline void feed(ppm::Decoder& decoder, const std::vector<Edge>& edges) {
  for (const Edge& e : edges) decoder.onEdge(e.high, e.t_us);
}

// Every frame the decoder accepts from `edges`.
inline std::vector<ppm::Frame> decodeAll(const std::vector<Edge>& edges,
                                         ppm::Decoder* keep = nullptr) {
  ppm::Decoder local;
  ppm::Decoder& decoder = keep ? *keep : local;
  std::vector<ppm::Frame> out;
  for (const Edge& e : edges) {
    decoder.onEdge(e.high, e.t_us);
    ppm::Frame f;
    if (decoder.takeFrame(f)) out.push_back(f);
  }
  return out;
}

struct SentFrame {
  uint32_t start_us;
  uint32_t length_us;
  arming::Mode mode;
  ppm::Frame frame;
  bool well_formed;  // alternating levels, separators exact
};

class Bench {
 public:
  arming::Emulator emu;
  std::vector<Edge> input;
  std::function<arming::RequestPins(uint32_t)> pins = [](uint32_t) {
    return arming::RequestPins{false, false};
  };
  std::vector<ppm::Segment> output;
  std::vector<uint32_t> output_at_us;
  std::vector<arming::Mode> mode_at_segment;

  void runUntil(uint32_t end_us) {
    for (;;) {
      const bool have_input = next_input_ < input.size();
      const uint32_t t_in = have_input ? input[next_input_].t_us : UINT32_MAX;
      if (have_input && t_in <= next_out_us_ && t_in < end_us) {
        emu.onInputEdge(input[next_input_].high, t_in);
        ++next_input_;
        continue;
      }
      if (next_out_us_ >= end_us) break;
      const ppm::Segment s = emu.nextOutputSegment(pins(next_out_us_), next_out_us_);
      output.push_back(s);
      output_at_us.push_back(next_out_us_);
      mode_at_segment.push_back(emu.mode());
      next_out_us_ += s.us;
    }
  }

  // The output cut into frames; only complete frames are returned.
  std::vector<SentFrame> sentFrames() const {
    std::vector<SentFrame> frames;
    const size_t n = ppm::kSegmentsPerFrame;
    for (size_t i = 0; i + n <= output.size(); i += n) {
      SentFrame f{output_at_us[i], 0, mode_at_segment[i], ppm::Frame{}, true};
      for (size_t k = 0; k < n; ++k) {
        const ppm::Segment& s = output[i + k];
        f.length_us += s.us;
        const bool expect_high = k % 2 == 1;
        if (s.high != expect_high) f.well_formed = false;
        if (!s.high && s.us != frames::kSeparatorUs) f.well_formed = false;
        if (s.high && k < n - 1) f.frame.pulse_us[k / 2] = s.us;
      }
      frames.push_back(f);
    }
    return frames;
  }

 private:
  size_t next_input_ = 0;
  uint32_t next_out_us_ = 0;
};

}  // namespace line
