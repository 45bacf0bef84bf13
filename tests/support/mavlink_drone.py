"""A simulated MAVLink drone on the ground's broker: the simulator and the real agent,
heartbeating every 0.5 s, for the end-to-end tests of what a drone reports."""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

from firmware.sim import start_simulator
from firmware.sim.fleet import agent_process, copy_gear
from runtime.processes import Supervised
from tests.onboard.mavlink.conftest import HOME, TIME_SCALE


@contextmanager
def simulated_mavlink_drone(
    drone_id: str, mqtt_url: str, directory: Path, sim_args: Sequence[str] = ()
) -> Iterator[None]:
    """The simulator (with `sim_args`) and the agent of `drone_id` until the block ends;
    the agent must then stop cleanly."""
    sim = start_simulator(
        home=HOME,
        time_scale=TIME_SCALE,
        fc="mavlink",
        extra_args=list(sim_args),
        log_file=directory / "sim.log",
    )
    copy_gear(directory)
    agent = agent_process(
        drone_id,
        directory,
        sim.link_url,
        mqtt_url,
        fc="mavlink",
        time_scale=TIME_SCALE,
        extra=["--heartbeat-interval", "0.5"],
    ).start()
    try:
        yield
    finally:
        assert isinstance(agent, Supervised) and agent.stop() == 0
        sim.stop()
