#include "arming.h"

namespace arming {

const char* modeName(Mode m) {
  switch (m) {
    case Mode::PassThrough: return "PASS_THROUGH";
    case Mode::Arming: return "ARMING";
    case Mode::Disarming: return "DISARMING";
    case Mode::Failsafe: return "FAILSAFE";
  }
  return "?";
}

ArmingSwitch::ArmingSwitch()
    : receiver_(ppm::safeFrame()),
      arm_(ppm::armFrame()),
      disarm_(ppm::disarmFrame()),
      safe_(ppm::safeFrame()),
      receiver_at_us_(0),
      request_since_us_(0),
      mode_(Mode::Failsafe),
      have_receiver_(false),
      request_was_high_(false),
      request_disarm_(false),
      request_stuck_(false) {}

void ArmingSwitch::onReceiverFrame(const ppm::Frame& frame, uint32_t now_us) {
  receiver_ = frame;
  receiver_at_us_ = now_us;
  have_receiver_ = true;
}

Mode ArmingSwitch::update(RequestPins pins, uint32_t now_us) {
  if (pins.request && !request_was_high_) {
    request_since_us_ = now_us;
    request_disarm_ = pins.disarm;
    request_stuck_ = false;
  }
  if (!pins.request) request_stuck_ = false;
  request_was_high_ = pins.request;
  // Latched, so a request held for 71 minutes cannot wrap back into "fresh".
  if (pins.request && now_us - request_since_us_ >= frames::kRequestMaxHoldUs) {
    request_stuck_ = true;
  }
  // Clearing the flag (not only comparing ages) keeps a stale frame from passing again
  // when the microsecond clock wraps during a long signal loss.
  if (have_receiver_ && now_us - receiver_at_us_ >= frames::kSignalLossTimeoutUs) {
    have_receiver_ = false;
  }

  if (pins.request && !request_stuck_) {
    mode_ = request_disarm_ ? Mode::Disarming : Mode::Arming;
  } else if (have_receiver_) {
    mode_ = Mode::PassThrough;
  } else {
    mode_ = Mode::Failsafe;
  }
  return mode_;
}

const ppm::Frame& ArmingSwitch::output() const {
  switch (mode_) {
    case Mode::PassThrough: return receiver_;
    case Mode::Arming: return arm_;
    case Mode::Disarming: return disarm_;
    case Mode::Failsafe: return safe_;
  }
  return safe_;
}

Emulator::Emulator() : next_segment_(0) { ppm::buildPulseTrain(ppm::safeFrame(), train_); }

void Emulator::onInputEdge(bool level_high, uint32_t t_us) {
  decoder_.onEdge(level_high, t_us);
  ppm::Frame frame;
  if (decoder_.takeFrame(frame)) switch_.onReceiverFrame(frame, t_us);
}

ppm::Segment Emulator::nextOutputSegment(RequestPins pins, uint32_t now_us) {
  if (next_segment_ == 0) {
    switch_.update(pins, now_us);
    ppm::buildPulseTrain(switch_.output(), train_);
  }
  const ppm::Segment seg = train_.seg[next_segment_];
  next_segment_ = static_cast<uint8_t>((next_segment_ + 1) % ppm::kSegmentsPerFrame);
  return seg;
}

}  // namespace arming
