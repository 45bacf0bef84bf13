// Arming-switch emulator for the Arduino Nano (ATmega328P, 16 MHz).
//
// Sits between the radio receiver and the flight controller: forwards
// the receiver's inverted PPM frames, sends the arming or disarming frame while the
// companion computer raises REQUEST, and sends the safe frame when the receiver is lost.
// All decisions live in arming.cpp / ppm.cpp (plain C++, host-tested); this file only
// wires them to the hardware:
//   D2  (INT0)  receiver PPM in: interrupt on every edge, timestamped from Timer1.
//   D9  (OC1A)  PPM out to the flight controller: Timer1 compare match flips the pin in
//               hardware, so output edges are exact whatever the interrupt latency.
//   D3          REQUEST from the Raspberry Pi (high = send the command frame).
//   D4          MODE from the Raspberry Pi (low = arm, high = disarm; latched on REQUEST rise).
//   D13 (LED)   on while a command frame is sent, blinking while the safe frame is sent.
//   USB serial  115200 baud, one status line a second: mode and received frames by verdict,
//               so dropped frames are counted and visible, never silent.
// Run `make -C firmware/arming_switch header` first: generated_frames.h comes from onboard/arming_frames.json.

#include "arming.h"
#include "generated_frames.h"

static_assert(frames::kPinReceiverIn == 2, "the receiver input must be D2 (INT0)");
static_assert(frames::kPinOutput == 9, "the PPM output must be D9 (OC1A, Timer1 hardware)");
static_assert(frames::kPinRequest <= 7 && frames::kPinMode <= 7,
              "REQUEST and MODE are read from port D (D0..D7) inside the interrupt");

namespace {

arming::Emulator emulator;

// Timer1 runs free at F_CPU / 8 = 2 MHz: 2 ticks per microsecond, wrapping every 32768 us.
constexpr uint8_t kTicksPerUs = 2;
constexpr uint32_t kUsPerOverflow = 32768UL;

volatile uint32_t timer1_overflows = 0;
volatile uint8_t led_mode = static_cast<uint8_t>(arming::Mode::Failsafe);

ppm::Segment current_segment;  // what D9 is sending now
uint32_t current_start_us = 0;

// Microseconds since power-up, wrapping at 2^32 like the logic expects. Interrupts must be
// off (we are only called from ISRs).
uint32_t microsFromTimer1() {
  const uint16_t ticks = TCNT1;
  uint32_t overflows = timer1_overflows;
  // An overflow that happened after this ISR started is pending but not yet counted.
  if ((TIFR1 & _BV(TOV1)) && ticks < 0x8000) ++overflows;
  return overflows * kUsPerOverflow + ticks / kTicksPerUs;
}

arming::RequestPins readRequestPins() {
  const uint8_t port = PIND;
  return arming::RequestPins{(port & _BV(frames::kPinRequest)) != 0,
                             (port & _BV(frames::kPinMode)) != 0};
}

// Compare-output mode for OC1A: set (high) or clear (low) the pin at the next match.
void levelAtNextMatch(bool high) {
  TCCR1A = high ? (_BV(COM1A1) | _BV(COM1A0)) : _BV(COM1A1);
}

}  // namespace

ISR(TIMER1_OVF_vect) { ++timer1_overflows; }

ISR(INT0_vect) {
  const uint32_t t_us = microsFromTimer1();
  emulator.onInputEdge((PIND & _BV(PD2)) != 0, t_us);
}

// Fires when the hardware has just put `current_segment`'s level on D9. Schedule its end
// and tell the hardware the level of the segment after it. The logic samples REQUEST/MODE
// when it is asked for a frame's first segment, i.e. at the start of the previous sync gap.
ISR(TIMER1_COMPA_vect) {
  const uint32_t next_start_us = current_start_us + current_segment.us;
  const ppm::Segment next = emulator.nextOutputSegment(readRequestPins(), next_start_us);
  OCR1A += static_cast<uint16_t>(current_segment.us * kTicksPerUs);
  levelAtNextMatch(next.high);
  current_segment = next;
  current_start_us = next_start_us;
  led_mode = static_cast<uint8_t>(emulator.mode());
}

void setup() {
  pinMode(frames::kPinReceiverIn, INPUT_PULLUP);  // unplugged receiver = idle high, no noise
  pinMode(frames::kPinRequest, INPUT);            // external pull-down: no Pi = no request
  pinMode(frames::kPinMode, INPUT);
  pinMode(frames::kPinOutput, OUTPUT);
  pinMode(LED_BUILTIN, OUTPUT);
  Serial.begin(115200);

  noInterrupts();
  // Take Timer1 over from the Arduino core's PWM setup: normal mode, prescaler 8.
  TCCR1B = 0;
  TCNT1 = 0;
  timer1_overflows = 0;
  levelAtNextMatch(true);
  TCCR1C = _BV(FOC1A);  // force D9 high (idle) right now
  // First segment starts 1 ms from now; everything after follows from segment lengths.
  const uint16_t first_match = 1000 * kTicksPerUs;
  current_start_us = first_match / kTicksPerUs;
  current_segment = emulator.nextOutputSegment(readRequestPins(), current_start_us);
  OCR1A = first_match;
  levelAtNextMatch(current_segment.high);
  TIFR1 = _BV(OCF1A) | _BV(TOV1);
  TIMSK1 = _BV(OCIE1A) | _BV(TOIE1);
  TCCR1B = _BV(CS11);

  EICRA = _BV(ISC00);  // INT0 on any logical change
  EIFR = _BV(INTF0);
  EIMSK = _BV(INT0);
  interrupts();
}

namespace {

void printStatus(arming::Mode mode) {
  // The counters are written by INT0: copy them with interrupts off, print with them on.
  noInterrupts();
  const ppm::DecoderStats stats = emulator.decoder().stats();
  const bool stuck = emulator.armingSwitch().requestStuck();
  interrupts();
  Serial.print(F("mode="));
  Serial.print(arming::modeName(mode));
  Serial.print(F(" stuck_request="));
  Serial.print(stuck ? 1 : 0);
  for (uint8_t i = 0; i < ppm::kVerdictCount; ++i) {
    Serial.print(F(" ["));
    Serial.print(ppm::verdictName(static_cast<ppm::Verdict>(i)));
    Serial.print(F("]="));
    Serial.print(stats.verdicts[i]);
  }
  Serial.print(F(" [missed edges]="));
  Serial.println(stats.missed_edges);
}

}  // namespace

void loop() {
  static uint32_t last_status_ms = 0;
  const arming::Mode mode = static_cast<arming::Mode>(led_mode);
  const bool command = mode == arming::Mode::Arming || mode == arming::Mode::Disarming;
  const bool blink = mode == arming::Mode::Failsafe && (millis() / 250) % 2 == 0;
  digitalWrite(LED_BUILTIN, command || blink ? HIGH : LOW);
  if (millis() - last_status_ms >= 1000) {
    last_status_ms = millis();
    printStatus(mode);
  }
}
