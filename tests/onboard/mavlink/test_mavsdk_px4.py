"""MAVSDK, an independent MAVLink implementation, flies the simulator's PX4 personality.

The simulator runs in this process (so the test reads its state directly) on a pty; the
MAVSDK client runs in a process of its own, in a network namespace of its own where the
machine allows one, so the flight also shows that MAVSDK needs no network at all.
"""

from __future__ import annotations

import json
import math
import shutil
import subprocess
import sys
import threading
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from firmware.sim.mavlink_server import MavlinkSession
from firmware.sim.server import PtyTransport, serve
from firmware.sim.vehicle import Vehicle, VehicleConfig
from onboard.navigation import ned_to_lla

from .conftest import HOME

CLIENT = Path(__file__).resolve().parents[2] / "support" / "mavsdk_client.py"
TIME_SCALE = 10.0
PHASE_TIMEOUT_S = 20.0
CLIENT_TIMEOUT_S = 150.0


@dataclass
class Track:
    """The simulated vehicle's path, sampled from its own state every 10 ms."""

    session: MavlinkSession
    points: list[tuple[float, float, float]] = field(default_factory=list)
    stop: threading.Event = field(default_factory=threading.Event)

    def run(self) -> None:
        while not self.stop.wait(0.01):
            self.points.append(tuple(self.session.vehicle.ned))

    def visits(self, targets: list[tuple[float, float, float]], radius: float) -> list[int]:
        """Indexes into `points` where each target was reached, in order (-1: never)."""
        found, start = [], 0
        for target in targets:
            at = next(
                (
                    i
                    for i in range(start, len(self.points))
                    if math.dist(self.points[i], target) < radius
                ),
                -1,
            )
            found.append(at)
            start = max(at, start)
        return found


@pytest.fixture
def px4() -> Iterator[tuple[MavlinkSession, PtyTransport, Track]]:
    session = MavlinkSession(
        vehicle=Vehicle(config=VehicleConfig(home=HOME)), time_scale=TIME_SCALE, autopilot="px4"
    )
    transport = PtyTransport()
    stopping = threading.Event()
    server = threading.Thread(target=serve, args=(session, transport, stopping.is_set), daemon=True)
    track = Track(session)
    tracker = threading.Thread(target=track.run, daemon=True)
    server.start()
    tracker.start()
    try:
        yield session, transport, track
    finally:
        track.stop.set()
        stopping.set()
        server.join(5)
        tracker.join(5)
        transport.close()


def isolated_prefix(trace: Path) -> list[str]:
    """`unshare --net` (as the mapped root user) when this machine lets us: the client then
    has no network but a loopback that is down; and `strace`, when installed, to record
    every socket it opens or connects (`trace`)."""
    prefix = []
    unshare = shutil.which("unshare")
    if unshare is not None:
        probe = subprocess.run([unshare, "--net", "--map-root-user", "true"], capture_output=True)
        if probe.returncode == 0:
            prefix += [unshare, "--net", "--map-root-user"]
    strace = shutil.which("strace")
    if strace is not None:
        prefix += [
            strace,
            "-f",
            "-qq",
            "-e",
            "trace=openat,socket,connect,bind,sendto",
            "-o",
            str(trace),
        ]
    return prefix


def run_client(plan: dict, trace: Path) -> tuple[list[dict], str]:
    argv = [*isolated_prefix(trace), sys.executable, str(CLIENT), json.dumps(plan)]
    try:
        done = subprocess.run(argv, capture_output=True, text=True, timeout=CLIENT_TIMEOUT_S)
    except subprocess.TimeoutExpired as exc:  # run() has killed the client already
        raise AssertionError(f"MAVSDK client hung; it printed {exc.stdout!r}") from None
    lines = [json.loads(line) for line in done.stdout.splitlines() if line.startswith("{")]
    return lines, done.stderr


def lla(north: float, east: float, up: float) -> tuple[float, float]:
    lat, lon, _ = ned_to_lla(north, east, -up, HOME)
    return lat, lon


def test_mavsdk_arms_takes_off_goes_to_a_point_flies_a_mission_and_returns(px4, tmp_path):
    session, transport, track = px4
    goto = (30.0, 20.0, 15.0)  # north, east, up (m from home)
    waypoints = [(60.0, 20.0, 20.0), (60.0, -20.0, 20.0), (20.0, -30.0, 12.0)]
    plan = {
        "url": f"serial://{transport.path}:57600",
        "takeoff_alt": 10.0,
        "goto": [*lla(*goto), HOME[2] + goto[2]],
        "mission": [[*lla(*w), w[2]] for w in waypoints],
        "timeout": PHASE_TIMEOUT_S,
    }
    trace = tmp_path / "client.strace"
    lines, stderr = run_client(plan, trace)
    phases = [line.get("phase") for line in lines]
    errors = [line["error"] for line in lines if "error" in line]
    assert not errors, (errors, phases, stderr[-3000:])
    assert phases == [
        "connected",
        "healthy",
        "armed",
        "took off",
        "arrived",
        "uploaded",
        "mission finished",
        "landed",
    ]
    assert lines[0]["autopilot"] == "PX4"
    if trace.exists():  # MAVSDK opened no internet socket: it fetched nothing, ran alone
        calls = trace.read_text()
        assert "libcmavsdk.so" in calls  # the trace saw MAVSDK's own library load
        assert "AF_INET" not in calls, [c for c in calls.splitlines() if "AF_INET" in c]
    finished = lines[phases.index("mission finished")]
    assert finished["current"] == finished["total"] == len(waypoints)

    # What the simulated autopilot did, from its own state.
    assert session.params["MIS_TAKEOFF_ALT"] == 10.0  # MAVSDK's PARAM_SET took
    assert session.stats.mission_uploads == 1
    navigation = [i for i in session.mission if i.command == mavlink.MAV_CMD_NAV_WAYPOINT]
    assert [(round(i.x, 6), round(i.y, 6), i.z) for i in navigation] == [
        (round(lat, 6), round(lon, 6), alt) for lat, lon, alt in plan["mission"]
    ]
    targets = [(0.0, 0.0, -10.0), (goto[0], goto[1], -goto[2])]
    targets += [(n, e, -up) for n, e, up in waypoints]
    visits = track.visits(targets, radius=1.0)
    assert -1 not in visits and visits == sorted(visits), visits
    highest = min(p[2] for p in track.points[visits[-1] :])
    assert highest <= -59.0  # PX4's return climbs to RTL_RETURN_ALT (60 m) first
    assert not session.armed
    assert math.dist(session.vehicle.ned, (0.0, 0.0, 0.0)) < 1.0  # landed at home
