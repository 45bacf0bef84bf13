"""The missions end-to-end harness (tests/missions/sky.py), with drones that
speak MAVLink: the simulator's MAVLink personality and the agent with `--fc mavlink`.
One Sky can mix both; UAVTalk drones are started as the harness starts them."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import uuid
from typing import Any

from firmware.sim import start_simulator
from onboard.launcher import GEAR_EXAMPLE
from tests.missions.conftest import point_at
from tests.missions.sky import HOME_ALT_MSL, ROOT, SimDrone, Sky


class MixedSky(Sky):
    def start_gateway(self) -> None:
        """A gateway with a clean session: these experiments never restart it, and a
        persistent session left by an earlier test's gateway on the module's broker keeps
        its share of the shared subscription (its messages would be lost to this one)."""
        from workers.counters import Counters
        from workers.gateway import Gateway

        tag = uuid.uuid4().hex[:8]
        self.gateway = Gateway(
            self.broker.url_for("ground"),
            client_id=f"gw-h12-{tag}",
            counters=Counters(f"gateway-h12-{tag}", flush_every=1e9),
        )
        self.gateway.start()
        assert self.gateway.wait_connected(10), "the gateway did not connect"

    def add_drone(  # type: ignore[override]
        self,
        drone_id: str,
        *,
        north: float = 0.0,
        east: float = 0.0,
        extra: list[str] = (),  # type: ignore[assignment]
        fc: str = "mavlink",
        **sim_options: Any,
    ) -> SimDrone:
        """Provision the drone and start its simulator (`sim_options` for start_simulator,
        e.g. battery_capacity_mah) and agent, speaking `fc`."""
        from fleet import credentials

        creds = credentials.provision(drone_id, self.organisation_slug)
        lat, lon = point_at(north, east)
        folder = self.tmp_path / drone_id
        folder.mkdir(parents=True)
        shutil.copytree(GEAR_EXAMPLE, folder / "gear")
        url = f"mqtt://{drone_id}:{creds.password}@127.0.0.1:{self.broker.port}"
        drone = SimDrone(drone_id, (lat, lon, HOME_ALT_MSL), folder, url)
        self.drones.append(drone)
        arming_line = folder / "arming_line"
        drone.sim = start_simulator(
            home=drone.home,
            time_scale=self.time_scale,
            fc=fc,
            arming_line=arming_line if fc == "uavtalk" else None,
            log_file=folder / "sim.log",
            **sim_options,
        )
        arming = ["--arming", f"sim-line:{arming_line}"] if fc == "uavtalk" else []
        env = dict(os.environ, PYTHONPATH=str(ROOT))
        with open(folder / "agent.log", "ab") as log:
            drone.agent = subprocess.Popen(
                [
                    sys.executable, "-m", "onboard",
                    "--drone-id", drone_id,
                    "--fc", fc,
                    "--link", drone.sim.link_url,
                    "--broker", drone.broker_url,
                    *arming,
                    "--gear-dir", str(folder / "gear"),
                    "--log-dir", str(folder / "logs"),
                    "--time-scale", str(self.time_scale),
                    "--heartbeat-interval", "0.3",
                    *extra,
                ],
                stdout=subprocess.DEVNULL,
                stderr=log,
                cwd=ROOT,
                env=env,
            )  # fmt: skip
        return drone
