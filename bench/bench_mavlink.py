"""A MAVLink drone against a UAVTalk drone in the same run.

Both are the simulator (same vehicle model, time scale 1) driven by the real drivers:
MAVLink over TCP (as to ArduPilot SITL), UAVTalk over a pty (as to a dRonin board on USB).

- `mavlink.command_rtt_p50`: COMMAND_LONG → COMMAND_ACK (MAV_CMD_SET_MESSAGE_INTERVAL
  for a stream already running, so the vehicle does not change); baseline: an acknowledged
  UAVTalk object write (OBJ_ACK → ACK) of FlightStatus with its current mode.
- `mavlink.telemetry_msgs_per_s`: MAVLink messages the driver's listeners receive per
  second with the driver's default stream rates; baseline: UAVTalk objects per second at
  the board's own update periods. Platform objects the MAVLink driver derives are left out.
"""

from __future__ import annotations

import time
from collections import Counter

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from bench.common import percentile, record
from firmware.sim import start_simulator
from onboard.fc.mavlink import MavlinkFlightController
from onboard.fc.uavtalk import UAVTalkFlightController

COMMANDS = 300
TELEMETRY_WINDOW_S = 10.0


def _rtts(call, count: int) -> list[float]:  # type: ignore[no-untyped-def]
    samples = []
    for _ in range(count):
        began = time.perf_counter()
        call()
        samples.append((time.perf_counter() - began) * 1000.0)
    return samples


def _rate(counter: Counter, names, window: float) -> float:  # type: ignore[no-untyped-def]
    before = sum(counter[n] for n in names())
    time.sleep(window)
    return (sum(counter[n] for n in names()) - before) / window


def main() -> None:
    mav_sim = start_simulator(fc="mavlink", time_scale=1.0)
    uav_sim = start_simulator(time_scale=1.0)
    mav = MavlinkFlightController(mav_sim.url)
    uav = UAVTalkFlightController(uav_sim.url)
    mav_counts: Counter[str] = Counter()
    uav_counts: Counter[str] = Counter()
    mav.add_listener(lambda name, ts, fields: mav_counts.update((name,)))
    uav.add_listener(lambda name, ts, fields: uav_counts.update((name,)))
    try:
        mav.start()
        uav.start()
        assert mav.wait_connected(10) and uav.wait_connected(10), "simulators did not connect"
        time.sleep(2.0)  # streams requested and running
        mode = uav.state.flight_mode
        mav_rtt = _rtts(
            lambda: mav.command_long(
                mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, mavlink.MAVLINK_MSG_ID_ATTITUDE, 1e5
            ),
            COMMANDS,
        )
        uav_rtt = _rtts(lambda: uav.write_object("FlightStatus", {"FlightMode": mode}), COMMANDS)
        record(
            "mavlink.command_rtt_p50",
            value=percentile(mav_rtt, 50),
            unit="ms",
            baseline_name="UAVTalk acked object write, same run",
            baseline_value=percentile(uav_rtt, 50),
            higher_is_better=False,
            goal="a MAVLink command acknowledged as fast as a UAVTalk write (ratio ≤ 1.5)",
            p90_ms=percentile(mav_rtt, 90),
            baseline_p90_ms=percentile(uav_rtt, 90),
            samples=COMMANDS,
        )
        mavlink_names = lambda: [n for n in mav_counts if n.isupper()]  # noqa: E731
        mav_rate = _rate(mav_counts, mavlink_names, TELEMETRY_WINDOW_S)
        uav_rate = _rate(uav_counts, lambda: list(uav_counts), TELEMETRY_WINDOW_S)
        record(
            "mavlink.telemetry_msgs_per_s",
            value=mav_rate,
            unit="messages/s",
            baseline_name="UAVTalk objects/s from the same simulator, same run",
            baseline_value=uav_rate,
            higher_is_better=True,
            goal="position and attitude at ≥ 10 Hz, like the UAVTalk board",
            mavlink_per_message={n: mav_counts[n] for n in sorted(mavlink_names())},
            codec_drops=mav.decoder_stats,
        )
    finally:
        mav.stop()
        uav.stop()
        mav_sim.stop()
        uav_sim.stop()


if __name__ == "__main__":
    main()
