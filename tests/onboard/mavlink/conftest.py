"""A MAVLink simulator per test, on its own TCP port, and a driver connected to it."""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Iterator
from typing import Any

import pytest

from firmware.sim import start_simulator
from onboard.fc.mavlink import MavlinkFlightController
from runtime import processes

# Simulated seconds per wall second: a 10 m climb takes about a quarter of a second.
TIME_SCALE = 20.0
HOME = (40.6303, -8.6575, 12.0)


def wait_for(predicate: Callable[[], Any], timeout: float, interval: float = 0.02) -> Any:
    """Polls more often than the shared default: simulated flights pass states quickly."""
    return processes.wait_for(predicate, timeout, interval)


@pytest.fixture
def autopilot() -> str:
    """The simulator's MAVLink flavour; parametrize a test over it to fly both autopilots."""
    return "ardupilot"


@pytest.fixture
def mav_sim(tmp_path, autopilot) -> Iterator[Any]:  # type: ignore[no-untyped-def]
    sim = start_simulator(
        home=HOME,
        time_scale=TIME_SCALE,
        fc="mavlink",
        extra_args=["--autopilot", autopilot],
        log_file=tmp_path / "sim.log",
    )
    try:
        yield sim
    finally:
        sim.stop()


class Recorder:
    """A telemetry listener that keeps every object it is given, by name."""

    def __init__(self) -> None:
        self.counts: Counter[str] = Counter()
        self.last: dict[str, dict] = {}

    def __call__(self, name: str, ts: float, fields: dict) -> None:
        self.counts[name] += 1
        self.last[name] = fields


@pytest.fixture
def recorder() -> Recorder:
    return Recorder()


@pytest.fixture
def fc(mav_sim, recorder) -> Iterator[MavlinkFlightController]:  # type: ignore[no-untyped-def]
    driver = MavlinkFlightController(mav_sim.link_url)
    driver.add_listener(recorder)
    driver.start()
    try:
        assert driver.wait_connected(5), "no HEARTBEAT from the MAVLink simulator"
        assert wait_for(lambda: driver.state.home is not None and driver.state.ned, 5)
        yield driver
    finally:
        driver.stop()
