// Decoding, validating and building PPM frames.
#include <cstdlib>

#include "check.h"
#include "line.h"

using line::frameOf;
using ppm::Frame;
using ppm::Segment;
using ppm::Verdict;

namespace {

// A receiver capture that starts mid-frame, with the few microseconds of jitter a real
// receiver shows, followed by three complete frames (values: the sticks of
// [Paula 2018], figure 4.17, then yaw and switches moved). Throttle 497 and switch 1502
// are inside the margin and clamp.
const Segment kRecorded[] = {
    {true, 734},   {false, 501}, {true, 1497}, {false, 499}, {true, 503},   {false, 500},
    {true, 9000},  {false, 499}, {true, 1002}, {false, 500}, {true, 998},   {false, 497},
    {true, 497},   {false, 502}, {true, 1001}, {false, 503}, {true, 1499},  {false, 498},
    {true, 504},   {false, 497}, {true, 10998}, {false, 496}, {true, 1003}, {false, 502},
    {true, 996},   {false, 504}, {true, 502},  {false, 500}, {true, 1250},  {false, 496},
    {true, 1502},  {false, 499}, {true, 501},  {false, 504}, {true, 10747}, {false, 501},
    {true, 1000},  {false, 500}, {true, 1001}, {false, 498}, {true, 499},   {false, 497},
    {true, 1498},  {false, 500}, {true, 1497}, {false, 499}, {true, 503},   {false, 496},
    {true, 10515}, {false, 500},
};

std::vector<Segment> recorded() {
  return std::vector<Segment>(std::begin(kRecorded), std::end(kRecorded));
}

// `count` frames with the given channel pulses and separators, each padded to `period_us`.
std::vector<Segment> customFrames(const std::vector<uint16_t>& pulses, uint16_t separator_us,
                                  uint16_t period_us, int count) {
  std::vector<Segment> one;
  uint32_t used = 0;
  for (uint16_t p : pulses) {
    one.push_back(Segment{false, separator_us});
    one.push_back(Segment{true, p});
    used += separator_us + p;
  }
  one.push_back(Segment{false, separator_us});
  used += separator_us;
  one.push_back(Segment{true, static_cast<uint16_t>(period_us - used)});
  // Lead with a sync so the first custom frame is measured; close with a falling edge.
  std::vector<Segment> segs{Segment{true, 9000}};
  std::vector<Segment> body = line::repeat(one, count);
  segs.insert(segs.end(), body.begin(), body.end());
  segs.push_back(Segment{false, 500});
  return segs;
}

std::vector<Segment> goodFrames(int count) {
  return customFrames({1000, 1000, 500, 1000, 1000, 1000}, 500, 20000, count);
}

uint32_t verdictCount(const ppm::Decoder& d, Verdict v) {
  return d.stats().verdicts[static_cast<uint8_t>(v)];
}

uint32_t sum(const std::vector<Segment>& segs) {
  uint32_t t = 0;
  for (const Segment& s : segs) t += s.us;
  return t;
}

}  // namespace

TEST(decodes_a_recorded_receiver_capture_into_channel_values) {
  ppm::Decoder d;
  const std::vector<Frame> got = line::decodeAll(line::edgesOf(recorded(), 0), &d);
  CHECK_EQ(got.size(), 3u);
  if (got.size() != 3u) return;
  CHECK(got[0] == frameOf(1002, 998, 500, 1001, 1499, 504));
  CHECK(got[1] == frameOf(1003, 996, 502, 1250, 1500, 501));
  CHECK(got[2] == frameOf(1000, 1001, 500, 1498, 1497, 503));
  CHECK_EQ(verdictCount(d, Verdict::Ok), 3u);
  CHECK_EQ(d.stats().missed_edges, 0u);
}

TEST(decodes_the_same_frames_when_the_microsecond_clock_wraps) {
  const std::vector<Frame> got = line::decodeAll(line::edgesOf(recorded(), 0xFFFFFFFFu - 30000u));
  CHECK_EQ(got.size(), 3u);
  if (got.size() == 3u) CHECK(got[1] == frameOf(1003, 996, 502, 1250, 1500, 501));
}

TEST(rejects_a_frame_with_too_few_channels) {
  ppm::Decoder d;
  const auto got = line::decodeAll(
      line::edgesOf(customFrames({1000, 1000, 500, 1000, 1000}, 500, 20000, 3), 0), &d);
  CHECK_EQ(got.size(), 0u);
  CHECK_EQ(verdictCount(d, Verdict::TooFewChannels), 3u);
  CHECK(d.lastVerdict() == Verdict::TooFewChannels);
}

TEST(rejects_a_frame_with_too_many_channels) {
  ppm::Decoder d;
  const auto got = line::decodeAll(
      line::edgesOf(customFrames({1000, 1000, 500, 1000, 1000, 1000, 1000}, 500, 20000, 2), 0),
      &d);
  CHECK_EQ(got.size(), 0u);
  CHECK_EQ(verdictCount(d, Verdict::TooManyChannels), 2u);
}

TEST(rejects_far_too_many_channels_without_overrunning_the_capture) {
  ppm::Decoder d;
  const std::vector<uint16_t> many(12, 700);
  const auto got = line::decodeAll(line::edgesOf(customFrames(many, 500, 20000, 2), 0), &d);
  CHECK_EQ(got.size(), 0u);
  CHECK_EQ(verdictCount(d, Verdict::TooManyChannels), 2u);
}

TEST(rejects_pulses_out_of_range_but_clamps_pulses_within_the_margin) {
  ppm::Decoder d;
  line::decodeAll(line::edgesOf(customFrames({1000, 1000, 440, 1000, 1000, 1000}, 500, 20000, 1), 0), &d);
  line::decodeAll(line::edgesOf(customFrames({1000, 1000, 500, 1000, 1560, 1000}, 500, 20000, 1), 0), &d);
  CHECK_EQ(verdictCount(d, Verdict::PulseOutOfRange), 2u);
  const auto got = line::decodeAll(
      line::edgesOf(customFrames({1000, 1000, 455, 1000, 1545, 1000}, 500, 20000, 1), 0));
  CHECK_EQ(got.size(), 1u);
  if (!got.empty()) CHECK(got[0] == frameOf(1000, 1000, 500, 1000, 1500, 1000));
}

TEST(rejects_separators_outside_the_jitter_tolerance) {
  ppm::Decoder d;
  CHECK_EQ(line::decodeAll(line::edgesOf(customFrames({1000, 1000, 500, 1000, 1000, 1000}, 650, 20000, 2), 0), &d).size(), 0u);
  CHECK_EQ(line::decodeAll(line::edgesOf(customFrames({1000, 1000, 500, 1000, 1000, 1000}, 380, 20000, 2), 0), &d).size(), 0u);
  CHECK_EQ(verdictCount(d, Verdict::SeparatorJitter), 4u);
  CHECK_EQ(line::decodeAll(line::edgesOf(customFrames({1000, 1000, 500, 1000, 1000, 1000}, 590, 20000, 2), 0)).size(), 2u);
}

TEST(rejects_a_frame_period_outside_the_jitter_tolerance) {
  ppm::Decoder d;
  CHECK_EQ(line::decodeAll(line::edgesOf(customFrames({1000, 1000, 500, 1000, 1000, 1000}, 500, 22500, 3), 0), &d).size(), 0u);
  CHECK_EQ(verdictCount(d, Verdict::PeriodJitter), 3u);
  CHECK_EQ(line::decodeAll(line::edgesOf(customFrames({1000, 1000, 500, 1000, 1000, 1000}, 500, 20800, 3), 0)).size(), 3u);
}

TEST(validate_reports_each_fault_on_a_captured_frame) {
  ppm::RawFrame raw{};
  for (uint8_t i = 0; i < 6; ++i) raw.pulse_us[i] = 1000;
  for (uint8_t i = 0; i < 7; ++i) raw.separator_us[i] = 500;
  raw.pulses = 6;
  raw.separators = 7;
  raw.period_us = 20000;
  Frame out{};
  CHECK(ppm::validate(raw, out) == Verdict::Ok);
  CHECK(out == frameOf(1000, 1000, 1000, 1000, 1000, 1000));
  ppm::RawFrame bad = raw;
  bad.separators = 6;
  CHECK(ppm::validate(bad, out) == Verdict::SeparatorJitter);
  bad = raw;
  bad.overflow = true;
  CHECK(ppm::validate(bad, out) == Verdict::TooManyChannels);
  bad = raw;
  bad.pulses = 0;
  CHECK(ppm::validate(bad, out) == Verdict::TooFewChannels);
  CHECK(std::string(ppm::verdictName(Verdict::PeriodJitter)) == "frame period jitter");
}

TEST(skips_noise_spikes_and_never_accepts_a_corrupted_frame) {
  // Clean frames with values that differ per frame, then spikes at pseudo-random places.
  std::vector<Segment> clean{Segment{true, 9000}};
  std::vector<Frame> sent;
  for (int i = 0; i < 200; ++i) {
    const Frame f = frameOf(600 + i, 1400 - i, 500, 1000 + i, 500 + 5 * i, 1500 - 5 * i);
    sent.push_back(f);
    const auto segs = line::segmentsOf(f);
    clean.insert(clean.end(), segs.begin(), segs.end());
  }
  clean.push_back(Segment{false, 500});
  std::vector<line::Edge> edges = line::edgesOf(clean, 1000);
  // After about one edge in 97, a spike pair: the opposite level for 3..40 us.
  uint32_t seed = 12345;
  std::vector<line::Edge> noisy;
  for (size_t i = 0; i < edges.size(); ++i) {
    noisy.push_back(edges[i]);
    seed = seed * 1103515245u + 12345u;
    if (i + 1 < edges.size() && (seed >> 16) % 97 == 0) {
      const uint32_t gap = edges[i + 1].t_us - edges[i].t_us;
      const uint32_t at = edges[i].t_us + 1 + (seed >> 8) % (gap - 45);
      const uint32_t width = 3 + (seed >> 4) % 38;
      noisy.push_back(line::Edge{!edges[i].high, at});
      noisy.push_back(line::Edge{edges[i].high, at + width});
    }
  }
  ppm::Decoder d;
  const std::vector<Frame> got = line::decodeAll(noisy, &d);
  // Every accepted frame is one that was really sent, in order.
  size_t cursor = 0;
  for (const Frame& f : got) {
    while (cursor < sent.size() && sent[cursor] != f) ++cursor;
    CHECK(cursor < sent.size());
  }
  const uint32_t rejected = d.stats().verdicts[1] + d.stats().verdicts[2] + d.stats().verdicts[3] +
                            d.stats().verdicts[4] + d.stats().verdicts[5];
  CHECK(rejected > 10u);
  CHECK(got.size() > 100u);
}

TEST(resynchronises_after_a_missed_edge) {
  std::vector<line::Edge> edges = line::edgesOf(goodFrames(4), 0);
  // Drop the falling edge that starts the fourth separator of the second frame.
  edges.erase(edges.begin() + 1 + 14 + 5);
  ppm::Decoder d;
  const auto got = line::decodeAll(edges, &d);
  CHECK_EQ(d.stats().missed_edges, 1u);
  // Frame 2 is lost; frame 3 starts at frame 2's sync end, so 1, 3 and 4 come through.
  CHECK_EQ(got.size(), 3u);
}

TEST(builds_the_arming_frame_with_exact_timings) {
  const auto segs = line::segmentsOf(ppm::armFrame());
  const Segment expected[] = {
      {false, 500}, {true, 1000}, {false, 500}, {true, 1000}, {false, 500},
      {true, 500},  {false, 500}, {true, 1500}, {false, 500}, {true, 1000},
      {false, 500}, {true, 1000}, {false, 500}, {true, 10500},
  };
  CHECK_EQ(segs.size(), 14u);
  for (size_t i = 0; i < 14 && i < segs.size(); ++i) {
    CHECK_EQ(segs[i].high, expected[i].high);
    CHECK_EQ(segs[i].us, expected[i].us);
  }
  CHECK_EQ(sum(segs), 20000u);
}

TEST(builds_the_disarming_and_safe_frames_with_exact_timings) {
  const auto disarm = line::segmentsOf(ppm::disarmFrame());
  CHECK_EQ(disarm[5].us, 500);   // throttle minimum
  CHECK_EQ(disarm[7].us, 500);   // yaw to the disarming side
  CHECK_EQ(disarm[13].us, 11500);
  CHECK_EQ(sum(disarm), 20000u);
  const auto safe = line::segmentsOf(ppm::safeFrame());
  CHECK_EQ(safe[5].us, 500);
  CHECK_EQ(safe[7].us, 1000);
  CHECK_EQ(safe[13].us, 11000);
  CHECK_EQ(sum(safe), 20000u);
}

TEST(builds_frames_that_the_decoder_reads_back_unchanged) {
  for (const Frame& f : {ppm::armFrame(), ppm::disarmFrame(), ppm::safeFrame(),
                         frameOf(1500, 1500, 1500, 1500, 1500, 1500)}) {
    std::vector<Segment> segs{Segment{true, 9000}};
    const auto body = line::repeat(line::segmentsOf(f), 2);
    segs.insert(segs.end(), body.begin(), body.end());
    segs.push_back(Segment{false, 500});
    const auto got = line::decodeAll(line::edgesOf(segs, 0));
    CHECK_EQ(got.size(), 2u);
    if (!got.empty()) CHECK(got[0] == f);
  }
}

TEST(clamps_out_of_range_values_when_building_a_frame) {
  const auto segs = line::segmentsOf(frameOf(0, 2000, 500, 1000, 1000, 1000));
  CHECK_EQ(segs[1].us, 500);
  CHECK_EQ(segs[3].us, 1500);
  CHECK_EQ(sum(segs), 20000u);
}
