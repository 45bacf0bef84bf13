"""Start N simulated drones: a flight-controller simulator and an onboard agent each.

This is the one simulated-fleet launcher: `make run` runs it (through `manage.py
run_simulated_drones`), and the end-to-end tests and benchmarks start their drones with
`start_drone()` (or an agent for a simulator of their own with `agent_process()`).

    python -m firmware.sim.fleet --count 3 --home 40.6303,-8.6575 \\
        --broker-url mqtt://127.0.0.1:1883 --credentials-file creds.json

Drones are spread around the home point on a spiral, each with its own folder (gear
files, flight logs, pictures, arming line, process logs). Broker credentials come from:

- `--credentials-file FILE`: JSON, one of
  * a list of `manage.py provision_drone` outputs:
    `[{"drone_id": "SIM_001", "mqtt": {"host": "127.0.0.1", "port": 1883,
       "username": "SIM_001", "password": "..."}}, ...]`
    (with `"urls": ["mqtt://host:port", ...]` in "mqtt", every node of a broker cluster:
    the agent tries them in turn)
  * the same objects one per line (JSON Lines), or
  * a mapping `{"SIM_001": {"username": "SIM_001", "password": "..."}, ...}`
    (a value may also be a whole provision output);
  the drone ids are the file's, in order.
- `--provision CMD`: a command run once per drone id that prints a provision output, e.g.
  `--provision ".venv/bin/python manage.py provision_drone"` (the id is appended, or
  substituted for `{drone_id}`).
- neither: every agent uses `--broker-url` as given.

`--broker-url` host and port (or several nodes, comma-separated), when given, override
the ones in the credentials.

`--fc-mix uavtalk,mavlink` (or the FC_MIX environment variable, as in
`make run DRONES=4 FC_MIX=uavtalk,mavlink`) gives the drones flight controllers of those
protocols in turn: UAVTalk simulators with an arming line, MAVLink ones on TCP.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shlex
import shutil
import subprocess
import sys
import threading
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import quote

import onboard
from firmware.sim import SimulatorProcess, start_simulator
from onboard import protocol
from onboard.mqtt import parse_broker_urls
from onboard.navigation import ned_to_lla
from runtime.processes import Supervised, python_env
from runtime.stopsignal import StopSignal

REPO_ROOT = Path(__file__).resolve().parents[2]
GEAR_EXAMPLE = Path(onboard.__file__).resolve().parent / "gear_example"
FC_PROTOCOLS = ("uavtalk", "mavlink")


class LaunchError(RuntimeError):
    pass


@dataclass(frozen=True)
class Credentials:
    drone_id: str
    username: str | None
    password: str | None
    host: str | None = None
    port: int | None = None
    urls: tuple[str, ...] = ()  # every node of the broker cluster, when it has several


def _credentials_from(obj: object, drone_id: str | None = None) -> Credentials:
    if not isinstance(obj, dict):
        raise LaunchError("each credentials entry must be a JSON object")
    mqtt = obj.get("mqtt", obj)
    if not isinstance(mqtt, dict):
        raise LaunchError("'mqtt' must be an object")
    drone_id = obj.get("drone_id", drone_id)
    if not protocol.is_drone_id(drone_id):
        raise LaunchError(f"invalid drone id {drone_id!r} in the credentials")
    port = mqtt.get("port")
    urls = mqtt.get("urls") or []
    if not isinstance(urls, list) or not all(isinstance(u, str) for u in urls):
        raise LaunchError("'mqtt.urls' must be a list of broker URLs")
    return Credentials(
        drone_id=str(drone_id),
        username=mqtt.get("username"),
        password=mqtt.get("password"),
        host=mqtt.get("host"),
        port=int(port) if port is not None else None,
        urls=tuple(u if "://" in u else f"mqtt://{u}" for u in urls),
    )


def parse_credentials(text: str) -> list[Credentials]:
    """Credentials in any of the accepted shapes (see the module docstring)."""
    text = text.strip()
    if not text:
        return []
    try:
        data = json.loads(text)
    except json.JSONDecodeError:
        try:
            data = [json.loads(line) for line in text.splitlines() if line.strip()]
        except json.JSONDecodeError as exc:
            raise LaunchError(f"credentials are not JSON or JSON Lines: {exc}") from None
    if isinstance(data, list):
        return [_credentials_from(item) for item in data]
    if isinstance(data, dict) and "drone_id" in data:
        return [_credentials_from(data)]
    if isinstance(data, dict):
        return [_credentials_from(value, key) for key, value in data.items()]
    raise LaunchError("credentials must be a list or an object")


def provision(command: str, drone_id: str) -> Credentials:
    """Run the provisioning command for one drone and parse what it prints."""
    parts = shlex.split(command)
    if any("{drone_id}" in p for p in parts):
        parts = [p.replace("{drone_id}", drone_id) for p in parts]
    else:
        parts.append(drone_id)
    result = subprocess.run(parts, capture_output=True, text=True, cwd=REPO_ROOT, timeout=120)
    if result.returncode != 0:
        raise LaunchError(f"provisioning {drone_id} failed: {result.stderr.strip()[-500:]}")
    # The command may log before its JSON: take the last line that parses.
    for line in reversed(result.stdout.strip().splitlines()):
        try:
            return _credentials_from(json.loads(line), drone_id)
        except (json.JSONDecodeError, LaunchError):
            continue
    raise LaunchError(f"provisioning {drone_id} printed no credentials JSON")


def broker_url_for(credentials: Credentials, default_url: str | None) -> str:
    """mqtt://user:pass@host:port from credentials, host/port overridden by default_url.

    A cluster (several nodes in default_url, comma-separated, or in the credentials'
    `urls`) gives one such URL per node, comma-separated, as the agent's --broker takes.
    """
    if default_url:
        if credentials.username is None:
            return default_url
        nodes = [(b.host, b.port) for b in parse_broker_urls(default_url)]
    elif credentials.urls:
        nodes = [(b.host, b.port) for b in parse_broker_urls(credentials.urls)]
    elif credentials.host is not None:
        nodes = [(credentials.host, credentials.port or 1883)]
    else:
        raise LaunchError(f"no broker host for {credentials.drone_id}: give --broker-url")
    auth = ""
    if credentials.username:
        auth = quote(credentials.username, safe="")
        if credentials.password is not None:
            auth += ":" + quote(credentials.password, safe="")
        auth += "@"
    return ",".join(f"mqtt://{auth}{host}:{port}" for host, port in nodes)


def spread(home: tuple[float, float, float], count: int, spacing: float) -> list[tuple]:
    """Positions on a sunflower spiral around home, about `spacing` metres apart."""
    golden = math.pi * (3 - math.sqrt(5))
    points = []
    for i in range(count):
        r = spacing * math.sqrt(i)
        north, east = r * math.cos(i * golden), r * math.sin(i * golden)
        lat, lon, _ = ned_to_lla(north, east, 0.0, home)
        points.append((round(lat, 7), round(lon, 7), home[2]))
    return points


def agent_process(
    drone_id: str,
    folder: Path,
    link: str,
    broker_url: str,
    *,
    fc: str = "uavtalk",
    arming_line: Path | None = None,
    time_scale: float = 1.0,
    extra: Sequence[str] = (),
) -> Supervised:
    """`python -m onboard` for one drone (not started): gear from `folder/gear`, flight
    logs in `folder/logs`, its output in `folder/agent.log`. A UAVTalk drone arms through
    the simulator's arming line unless `extra` says otherwise."""
    arming = ["--arming", f"sim-line:{arming_line}"] if arming_line is not None else []
    argv = [
        sys.executable, "-m", "onboard",
        "--drone-id", drone_id,
        "--fc", fc,
        "--link", link,
        "--broker", broker_url,
        *arming,
        "--gear-dir", str(folder / "gear"),
        "--log-dir", str(folder / "logs"),
        "--time-scale", str(time_scale),
        *extra,
    ]  # fmt: skip
    # In the launcher's process group: whatever ends the launcher's group ends its agents.
    return Supervised(
        f"agent {drone_id}", argv, python_env(), folder / "agent.log", own_group=False
    )


def copy_gear(folder: Path, template: Path = GEAR_EXAMPLE) -> Path:
    """The drone's gear folder, copied from `template` the first time."""
    gear = folder / "gear"
    if not gear.exists():
        folder.mkdir(parents=True, exist_ok=True)
        shutil.copytree(template, gear)
    return gear


@dataclass
class Drone:
    """A software flight controller (`python -m firmware.sim`) and the real onboard agent."""

    drone_id: str
    folder: Path
    home: tuple[float, float, float]
    broker_url: str
    sim: SimulatorProcess | None = None
    agent: Supervised | None = None
    restarts: int = 0
    fc: str = "uavtalk"
    # start_simulator's options beyond home and time scale, e.g. battery_capacity_mah
    sim_options: dict[str, Any] = field(default_factory=dict)

    @property
    def arming_line(self) -> Path:
        return self.folder / "arming_line"

    def start(self, time_scale: float, agent_args: Sequence[str] = ()) -> Drone:
        copy_gear(self.folder)
        self.start_sim(time_scale)
        try:
            self.start_agent(time_scale, agent_args)
        except BaseException:
            self.stop()  # no simulator left behind without its agent
            raise
        return self

    def start_sim(self, time_scale: float) -> None:
        self.sim = start_simulator(
            home=self.home,
            time_scale=time_scale,
            arming_line=self.arming_line if self.fc == "uavtalk" else None,
            log_file=self.folder / "sim.log",
            fc=self.fc,
            **self.sim_options,
        )

    def start_agent(self, time_scale: float, agent_args: Sequence[str] = ()) -> None:
        self.agent = agent_process(
            self.drone_id,
            self.folder,
            self.sim.url,
            self.broker_url,
            fc=self.fc,
            arming_line=self.arming_line if self.fc == "uavtalk" else None,
            time_scale=time_scale,
            extra=agent_args,
        ).start()

    def stop(self) -> None:
        if self.agent is not None:
            self.agent.stop(10)
        if self.sim is not None:
            self.sim.stop()


def start_drone(
    folder: Path,
    drone_id: str,
    broker_url: str,
    home: tuple[float, float, float],
    *,
    time_scale: float,
    fc: str = "uavtalk",
    agent_args: Sequence[str] = (),
    **sim_options: Any,
) -> Drone:
    """Start one drone; `broker_url` carries its credentials (several nodes: comma-separated)."""
    drone = Drone(drone_id, folder, home, broker_url, fc=fc, sim_options=sim_options)
    return drone.start(time_scale, agent_args)


@dataclass
class Fleet:
    drones: list[Drone]
    time_scale: float
    agent_args: list[str] = field(default_factory=list)
    _stopping: threading.Event = field(default_factory=threading.Event)
    # watch() and stop() never interleave: a restart cannot slip in after a stop.
    _lock: threading.Lock = field(default_factory=threading.Lock)

    def start(self) -> None:
        for drone in self.drones:
            drone.start(self.time_scale, self.agent_args)

    def restart_agent(self, drone: Drone) -> None:
        drone.start_agent(self.time_scale, self.agent_args)

    def watch(self) -> None:
        """Restart what exits on its own, until stop() (one second backoff).

        A simulator that died comes back on a new pty, so its agent is restarted with it.
        """
        while not self._stopping.wait(1.0):
            with self._lock:
                if not self._stopping.is_set():
                    self._revive()

    def _revive(self) -> None:
        for drone in self.drones:
            if drone.sim is not None and not drone.sim.alive():
                _say(f"simulator of {drone.drone_id} exited; restarting it and its agent")
                if drone.agent is not None:
                    drone.agent.stop(10)
                try:
                    drone.start_sim(self.time_scale)
                except Exception as exc:
                    _say(f"simulator of {drone.drone_id} did not restart: {exc}")
                    continue
            if drone.agent is not None and not drone.agent.alive:
                drone.restarts += 1
                code = drone.agent.process.returncode if drone.agent.process else None
                _say(f"agent {drone.drone_id} exited ({code}); restarting")
                self.restart_agent(drone)

    def stop(self) -> None:
        self._stopping.set()
        with self._lock:
            self._stop_all()

    def _stop_all(self) -> None:
        # Every agent is asked at once, so they drain in parallel.
        for drone in self.drones:
            if drone.agent is not None and drone.agent.alive:
                drone.agent.process.terminate()  # type: ignore[union-attr]
        for drone in self.drones:
            drone.stop()


def _say(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


def plan_fleet(
    *,
    count: int,
    home: tuple[float, float, float],
    workdir: Path,
    credentials: list[Credentials],
    broker_url: str | None,
    provision_command: str | None = None,
    prefix: str = "SIM",
    spacing: float = 15.0,
    time_scale: float = 1.0,
    gear_template: Path = GEAR_EXAMPLE,
    agent_args: list[str] | None = None,
    fc_mix: tuple[str, ...] = ("uavtalk",),
) -> Fleet:
    """Decide ids, credentials, homes and folders (no process is started)."""
    if count < 1:
        raise LaunchError("--count must be at least 1")
    if credentials:
        if len(credentials) < count:
            raise LaunchError(f"{count} drones asked for, {len(credentials)} credentials given")
        chosen = credentials[:count]
    else:
        ids = [f"{prefix}_{i + 1:03d}" for i in range(count)]
        if provision_command:
            chosen = [provision(provision_command, drone_id) for drone_id in ids]
        elif broker_url:
            chosen = [Credentials(drone_id, None, None) for drone_id in ids]
        else:
            raise LaunchError("give --credentials-file, --provision or --broker-url")
    unknown = [fc for fc in fc_mix if fc not in FC_PROTOCOLS]
    if not fc_mix or unknown:
        raise LaunchError(f"the protocol mix takes {' and '.join(FC_PROTOCOLS)}, not {unknown}")
    drones = []
    for number, (creds, position) in enumerate(
        zip(chosen, spread(home, count, spacing), strict=True)
    ):
        folder = workdir / creds.drone_id
        copy_gear(folder, gear_template)
        drones.append(
            Drone(
                creds.drone_id,
                folder,
                position,
                broker_url_for(creds, broker_url),
                fc=fc_mix[number % len(fc_mix)],
            )
        )
    return Fleet(drones, time_scale, list(agent_args or []))


def _home(text: str) -> tuple[float, float, float]:
    parts = [float(p) for p in text.split(",")]
    if len(parts) == 2:
        parts.append(0.0)
    if len(parts) != 3 or not (-90 <= parts[0] <= 90 and -180 <= parts[1] <= 180):
        raise argparse.ArgumentTypeError("home is LAT,LON[,ALT]")
    return parts[0], parts[1], parts[2]


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m firmware.sim.fleet",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--count", type=int, required=True)
    p.add_argument("--home", type=_home, required=True, help="LAT,LON[,ALT]")
    p.add_argument(
        "--broker-url",
        help="mqtt://host:port (credentials may be included); a cluster's nodes comma-separated",
    )
    source = p.add_mutually_exclusive_group()
    source.add_argument("--credentials-file", type=Path)
    source.add_argument("--provision", help="command printing provision_drone JSON for an id")
    p.add_argument("--prefix", default="SIM", help="drone id prefix when ids are generated")
    p.add_argument("--spacing", type=float, default=15.0, help="metres between drones")
    p.add_argument("--time-scale", type=float, default=1.0)
    p.add_argument("--workdir", type=Path, default=Path(".data/fleet"))
    p.add_argument("--gear-template", type=Path, default=GEAR_EXAMPLE)
    p.add_argument(
        "--fc-mix",
        default=os.environ.get("FC_MIX") or "uavtalk",
        help="flight-controller protocols given in turn, e.g. uavtalk,mavlink (env FC_MIX)",
    )
    p.add_argument("agent_args", nargs="*", help="extra agent flags, after --")
    return p


def _fleet_from(args: argparse.Namespace) -> Fleet:
    credentials = []
    if args.credentials_file is not None:
        credentials = parse_credentials(args.credentials_file.read_text())
    return plan_fleet(
        count=args.count,
        home=args.home,
        workdir=args.workdir.resolve(),
        credentials=credentials,
        broker_url=args.broker_url,
        provision_command=args.provision,
        prefix=args.prefix,
        spacing=args.spacing,
        time_scale=args.time_scale,
        gear_template=args.gear_template,
        agent_args=args.agent_args,
        fc_mix=tuple(p.strip() for p in args.fc_mix.split(",") if p.strip()),
    )


def _stop_on_signals() -> StopSignal:
    """A stop SIGTERM and SIGINT make (from now on, so a signal while starting counts)."""
    return StopSignal().install()


def _run_until(fleet: Fleet, stop: StopSignal) -> None:
    """Print each drone, keep the fleet alive until `stop` is set, then stop it."""
    for drone in fleet.drones:
        print(
            f"drone: {drone.drone_id} fc={drone.fc} link={drone.sim.url} "
            f"agent_pid={drone.agent.pid if drone.agent else None} folder={drone.folder}",
            flush=True,
        )
    threading.Thread(target=fleet.watch, daemon=True).start()
    while not stop.wait(1.0):
        pass
    fleet.stop()


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        fleet = _fleet_from(args)
    except (LaunchError, OSError, ValueError) as exc:
        print(f"firmware.sim.fleet: {exc}", file=sys.stderr)
        return 2
    stop = _stop_on_signals()
    try:
        fleet.start()
    except Exception as exc:
        print(f"firmware.sim.fleet: {exc}", file=sys.stderr)
        fleet.stop()
        return 1
    _run_until(fleet, stop)
    return 0


if __name__ == "__main__":
    sys.exit(main())
