"""The flight controller's own log of a flight, fetched by the driver over MAVLink's log
protocol from the simulated ArduPilot (its DataFlash .bin, read back with pymavlink's
DFReader): cut off by an arming it resumes from its part file, and it is no telemetry."""

from __future__ import annotations

import pytest
from pymavlink import DFReader

from onboard.fc.mavlink_logs import LINK_SHARE, FetchPaused, LogFetcher, link_capacity, paced

from .conftest import wait_for

ALTITUDE = 6.0


def _fly(fc) -> None:  # type: ignore[no-untyped-def]
    fc.arm(timeout=5)
    fc.takeoff(ALTITUDE)
    assert wait_for(lambda: -(fc.state.ned or (0, 0, 0))[2] > ALTITUDE - 0.5, 20)
    fc.land()
    assert wait_for(lambda: not fc.state.armed, 30)


def test_the_log_comes_down_whole_after_an_interruption(fc, recorder, tmp_path):
    _fly(fc)
    first = LogFetcher(fc, tmp_path, armed=lambda: first.windows >= 3)
    with pytest.raises(FetchPaused):
        first.fetch_newest("bin", "flight")
    (part,) = tmp_path.glob("*.part")
    kept = part.stat().st_size
    assert kept == 3 * first.window
    seen = sum(recorder.counts.values())

    # A restarted agent's, paced slower: the rest takes a few seconds of the link.
    again = LogFetcher(fc, tmp_path, rate=8 * 1024, armed=lambda: False)
    path = again.fetch_newest("bin", "flight")
    assert path is not None and not part.exists()
    size = path.stat().st_size
    assert again.requested_bytes == size - kept  # from the part file's end, not from 0
    reader = DFReader.DFReader_binary(str(path))
    heights, events = [], []
    while (m := reader.recv_msg()) is not None:
        if m.get_type() == "POS":
            heights.append(m.RelHomeAlt)
        elif m.get_type() == "EV":
            events.append(m.Id)
    assert events == [10, 11]  # armed, disarmed: the whole flight
    assert max(heights) == pytest.approx(ALTITUDE, abs=0.5)
    # Telemetry went on during the download; the log's bytes were never telemetry.
    assert sum(recorder.counts.values()) > seen
    assert recorder.counts["LOG_DATA"] == recorder.counts["LOG_ENTRY"] == 0


def test_on_a_serial_link_the_fetch_takes_at_most_half_of_it():
    capacity = link_capacity("serial:/dev/ttyAMA0?baud=57600")
    assert capacity == 5760.0
    rate, window = paced(32 * 1024, capacity)
    assert rate == capacity * LINK_SHARE
    assert window == 720  # a quarter second of that rate, in whole LOG_DATA
    assert paced(32 * 1024, link_capacity("tcp://127.0.0.1:5760")) == (32 * 1024, 2880)
