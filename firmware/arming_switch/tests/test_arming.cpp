// The arming-switch state machine and the whole emulator on virtual time.
#include "check.h"
#include "line.h"

using arming::Mode;
using arming::RequestPins;
using line::frameOf;
using ppm::Frame;

namespace {

const Frame kPilot = frameOf(1100, 900, 800, 1050, 1500, 500);

// Receiver frames of `frame` from `start_us` for `count` frames; the line then stays high.
std::vector<line::Edge> receiver(const Frame& frame, uint32_t start_us, int count,
                                 bool level_before = false) {
  std::vector<ppm::Segment> segs{ppm::Segment{true, 9000}};
  const auto body = line::repeat(line::segmentsOf(frame), count);
  segs.insert(segs.end(), body.begin(), body.end());
  segs.push_back(ppm::Segment{false, 500});
  return line::edgesOf(segs, start_us, level_before);
}

RequestPins requestBetween(uint32_t t, uint32_t from_us, uint32_t to_us, bool disarm) {
  return RequestPins{t >= from_us && t < to_us, disarm};
}

// Every frame is whole, exactly 20 ms long, and follows the previous one without a gap.
void checkOutputNeverStops(const line::Bench& bench, uint32_t until_us) {
  const auto sent = bench.sentFrames();
  CHECK(!sent.empty());
  uint32_t expected_start = 0;
  for (const line::SentFrame& f : sent) {
    CHECK(f.well_formed);
    CHECK_EQ(f.length_us, 20000u);
    CHECK_EQ(f.start_us, expected_start);
    expected_start += 20000;
  }
  CHECK(expected_start + 20000 >= until_us);
}

}  // namespace

TEST(sends_the_safe_frame_from_power_up_without_a_receiver) {
  line::Bench bench;
  bench.runUntil(200000);
  for (const line::SentFrame& f : bench.sentFrames()) {
    CHECK(f.mode == Mode::Failsafe);
    CHECK(f.frame == ppm::safeFrame());
  }
  checkOutputNeverStops(bench, 200000);
}

TEST(passes_the_receiver_frames_through_unchanged) {
  line::Bench bench;
  bench.input = receiver(kPilot, 3000, 50);
  bench.runUntil(1000000);
  const auto sent = bench.sentFrames();
  int passed = 0;
  for (const line::SentFrame& f : sent) {
    if (f.start_us < 40000) continue;  // the first receiver frame completes at ~32 ms
    CHECK(f.mode == Mode::PassThrough);
    CHECK(f.frame == kPilot);
    ++passed;
  }
  CHECK(passed >= 45);
  checkOutputNeverStops(bench, 1000000);
}

TEST(sends_the_arming_frame_while_request_is_high_and_falls_back_at_the_next_frame) {
  line::Bench bench;
  bench.input = receiver(kPilot, 3000, 60);
  bench.pins = [](uint32_t t) { return requestBetween(t, 305000, 805000, false); };
  bench.runUntil(1100000);
  for (const line::SentFrame& f : bench.sentFrames()) {
    if (f.start_us < 40000) continue;
    if (f.start_us >= 320000 && f.start_us < 820000) {
      CHECK(f.mode == Mode::Arming);
      CHECK(f.frame == ppm::armFrame());
    } else {
      CHECK(f.mode == Mode::PassThrough);
      CHECK(f.frame == kPilot);
    }
  }
  checkOutputNeverStops(bench, 1100000);
}

TEST(sends_the_disarming_frame_when_the_mode_pin_is_high) {
  line::Bench bench;
  bench.input = receiver(kPilot, 3000, 30);
  bench.pins = [](uint32_t t) { return requestBetween(t, 100000, 400000, true); };
  bench.runUntil(600000);
  for (const line::SentFrame& f : bench.sentFrames()) {
    if (f.start_us >= 100000 && f.start_us < 400000) {
      CHECK(f.mode == Mode::Disarming);
      CHECK(f.frame == ppm::disarmFrame());
    } else if (f.start_us >= 40000) {
      CHECK(f.mode == Mode::PassThrough);
    }
  }
}

TEST(latches_the_mode_pin_when_the_request_rises) {
  line::Bench bench;
  // Mode flips to disarm halfway through an arm request: still arming until the request ends.
  bench.pins = [](uint32_t t) { return RequestPins{t >= 100000 && t < 500000, t >= 300000}; };
  bench.runUntil(800000);
  for (const line::SentFrame& f : bench.sentFrames()) {
    if (f.start_us >= 100000 && f.start_us < 500000) {
      CHECK(f.mode == Mode::Arming);
    } else {
      CHECK(f.mode == Mode::Failsafe);
    }
  }
}

TEST(arms_without_a_receiver_and_returns_to_the_safe_frame) {
  line::Bench bench;
  bench.pins = [](uint32_t t) { return requestBetween(t, 60000, 3600000, false); };
  bench.runUntil(4000000);
  int arming_frames = 0;
  for (const line::SentFrame& f : bench.sentFrames()) {
    if (f.mode == Mode::Arming) {
      ++arming_frames;
      CHECK(f.frame == ppm::armFrame());
    } else {
      CHECK(f.frame == ppm::safeFrame());
    }
  }
  // 3.54 s of arming frames: longer than the flight controller's 3 s arming time.
  CHECK_EQ(arming_frames, 177);
  checkOutputNeverStops(bench, 4000000);
}

TEST(ignores_a_stuck_high_request_after_the_maximum_hold_until_the_line_drops) {
  line::Bench bench;
  bench.input = receiver(kPilot, 3000, 14 * 50);
  const uint32_t rise = 100000;
  const uint32_t drop = 13000000;
  const uint32_t again = 13500000;
  bench.pins = [=](uint32_t t) { return RequestPins{(t >= rise && t < drop) || t >= again, false}; };
  bench.runUntil(14000000);
  const uint32_t expires = rise + frames::kRequestMaxHoldUs;
  for (const line::SentFrame& f : bench.sentFrames()) {
    if (f.start_us < 40000) continue;
    const bool held = f.start_us >= rise && f.start_us < expires;
    const bool rearmed = f.start_us >= again;
    if (held || rearmed) {
      CHECK(f.mode == Mode::Arming);
    } else {
      CHECK(f.mode == Mode::PassThrough);
      CHECK(f.frame == kPilot);
    }
  }
  checkOutputNeverStops(bench, 14000000);
}

TEST(reports_a_stuck_request_until_the_line_drops) {
  arming::ArmingSwitch sw;
  CHECK(sw.update(RequestPins{true, false}, 0) == Mode::Arming);
  CHECK(sw.update(RequestPins{true, false}, frames::kRequestMaxHoldUs - 1) == Mode::Arming);
  CHECK(sw.update(RequestPins{true, false}, frames::kRequestMaxHoldUs) == Mode::Failsafe);
  CHECK(sw.requestStuck());
  CHECK(sw.update(RequestPins{false, false}, frames::kRequestMaxHoldUs + 20000) == Mode::Failsafe);
  CHECK(!sw.requestStuck());
  CHECK(sw.update(RequestPins{true, true}, frames::kRequestMaxHoldUs + 40000) == Mode::Disarming);
}

TEST(keeps_sending_the_safe_frame_when_the_receiver_is_unplugged_mid_frame) {
  line::Bench bench;
  std::vector<line::Edge> edges = receiver(kPilot, 3000, 25);
  // Cut the line 4 edges into frame 20 (mid-frame, line left high by the pull-up), then
  // plug it back in at 2 s.
  edges.resize(2 + 19 * 14 + 4);
  if (!edges.back().high) edges.pop_back();
  const auto back = receiver(kPilot, 2000000, 25, true);
  edges.insert(edges.end(), back.begin(), back.end());
  bench.input = edges;
  bench.runUntil(3000000);
  const uint32_t cut_us = 3000 + 9000 + 19 * 20000;
  for (const line::SentFrame& f : bench.sentFrames()) {
    if (f.start_us < 40000) continue;
    if (f.start_us < cut_us) {
      CHECK(f.mode == Mode::PassThrough);
    } else if (f.start_us >= cut_us + frames::kSignalLossTimeoutUs && f.start_us < 2000000) {
      CHECK(f.mode == Mode::Failsafe);
      CHECK(f.frame == ppm::safeFrame());
    } else if (f.start_us >= 2060000 && f.start_us < 2500000) {
      CHECK(f.mode == Mode::PassThrough);
      CHECK(f.frame == kPilot);
    }
  }
  checkOutputNeverStops(bench, 3000000);
  CHECK(bench.emu.decoder().stats().verdicts[0] >= 40u);
}

TEST(does_not_revive_a_stale_receiver_frame_when_the_clock_wraps) {
  arming::ArmingSwitch sw;
  sw.onReceiverFrame(kPilot, 0);
  CHECK(sw.update(RequestPins{false, false}, 50000) == Mode::PassThrough);
  CHECK(sw.update(RequestPins{false, false}, 200000) == Mode::Failsafe);
  // 2^32 us later the age would read 20 ms again.
  CHECK(sw.update(RequestPins{false, false}, 20000) == Mode::Failsafe);
  CHECK(sw.output() == ppm::safeFrame());
}

TEST(the_flight_controller_reads_the_arming_frame_from_the_output_line) {
  line::Bench bench;
  bench.pins = [](uint32_t t) { return requestBetween(t, 0, 500000, false); };
  bench.runUntil(1000000);
  const auto got = line::decodeAll(line::edgesOf(bench.output, 0));
  CHECK(got.size() >= 45u);
  int arm = 0;
  for (const Frame& f : got) {
    if (f == ppm::armFrame()) ++arm;
    else CHECK(f == ppm::safeFrame());
  }
  CHECK(arm >= 23);
  CHECK(std::string(arming::modeName(Mode::Disarming)) == "DISARMING");
}
