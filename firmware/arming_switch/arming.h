// The arming-switch state machine and the glue the sketch's interrupts call.
// Plain C++ like ppm.h, so the host tests drive exactly what runs on the Nano.
//
// Pins (onboard/arming_frames.json "pins"): REQUEST (D3) high = send a command frame instead of the
// receiver's; MODE (D4) low = arm, high = disarm, latched when REQUEST rises so a noisy
// MODE line cannot flip an arm into a disarm mid-request.
//
// Modes, decided once per output frame (every 20 ms):
//   ARMING / DISARMING  REQUEST high for less than kRequestMaxHoldUs (with or without a
//                       receiver: the platform must arm without a radio transmitter).
//   PASS_THROUGH        otherwise, while a valid receiver frame arrived within
//                       kSignalLossTimeoutUs: the last receiver frame is regenerated.
//   FAILSAFE            otherwise: the safe frame (throttle minimum, others neutral).
// A REQUEST held past kRequestMaxHoldUs is treated as stuck: the emulator ignores it (pass
// through or failsafe) until the line drops; the next rising edge is a new request.
// The output never stops: every mode sends a full 20 ms frame.
#pragma once

#include <stdint.h>

#include "ppm.h"

namespace arming {

enum class Mode : uint8_t { PassThrough, Arming, Disarming, Failsafe };

const char* modeName(Mode m);

struct RequestPins {
  bool request;  // REQUEST pin level
  bool disarm;   // MODE pin level: false = arm, true = disarm
};

class ArmingSwitch {
 public:
  ArmingSwitch();
  // A validated frame from the receiver arrived at `now_us`.
  void onReceiverFrame(const ppm::Frame& frame, uint32_t now_us);
  // Sample the pins and pick the mode for the frame that starts at `now_us`.
  Mode update(RequestPins pins, uint32_t now_us);
  Mode mode() const { return mode_; }
  // The frame to send in the current mode.
  const ppm::Frame& output() const;
  // True while a stuck-high REQUEST is being ignored.
  bool requestStuck() const { return request_stuck_; }

 private:
  ppm::Frame receiver_;
  ppm::Frame arm_;
  ppm::Frame disarm_;
  ppm::Frame safe_;
  uint32_t receiver_at_us_;
  uint32_t request_since_us_;
  Mode mode_;
  bool have_receiver_;
  bool request_was_high_;
  bool request_disarm_;
  bool request_stuck_;
};

// Everything between the two interrupts: input edges in, output segments out.
class Emulator {
 public:
  Emulator();
  // Pin-change interrupt on the receiver input.
  void onInputEdge(bool level_high, uint32_t t_us);
  // Output timer: the segment that starts at `now_us`. At each frame start the pins are
  // sampled and the next frame chosen, so a request takes effect within one frame.
  ppm::Segment nextOutputSegment(RequestPins pins, uint32_t now_us);
  Mode mode() const { return switch_.mode(); }
  const ArmingSwitch& armingSwitch() const { return switch_; }
  const ppm::Decoder& decoder() const { return decoder_; }

 private:
  ppm::Decoder decoder_;
  ArmingSwitch switch_;
  ppm::PulseTrain train_;
  uint8_t next_segment_;
};

}  // namespace arming
