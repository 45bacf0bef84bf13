"""The drone's own wind rule end to end: the real agent on a simulated PX4 or ArduPilot
that reports its wind (WIND_COV, WIND), a private Mosquitto, the ground a plain MQTT
client. The drone refuses a take-off above its gear's limit, returns home when the wind
rises above it in flight, and flies on below it."""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

import pytest

from firmware.sim.wind import write_wind
from onboard import protocol
from tests.onboard.ground import Ground

from .conftest import HOME
from .test_agent import broker, fly  # noqa: F401 (fixtures)

pytestmark = pytest.mark.e2e

LIMIT = 8.0
BOTH = pytest.mark.parametrize("autopilot", ["px4", "ardupilot"])


@pytest.fixture
def windy(tmp_path: Path, fly):  # type: ignore[no-untyped-def]  # noqa: F811
    """windy(speed) → (Ground, wind file): an agent whose gear limits the wind to LIMIT,
    flying a simulator in a wind of `speed` m/s from the west, changed by the file."""

    def start(speed: float) -> tuple[Ground, Path]:
        wind_file = tmp_path / "wind"
        write_wind(wind_file, speed, 270.0)
        gear = tmp_path / "gear"
        gear.mkdir()
        (gear / "specs.json").write_text(json.dumps({"TYPE": "QUADCOPTER", "MAX_WIND_M_S": LIMIT}))
        ground = fly(agent_args=("--wind-hold", "3"), sim_args=("--wind-file", str(wind_file)))
        ground.wait_for("heartbeats", lambda m: (m.get("wind") or {}).get("limit"), 20)
        return ground, wind_file

    return start


def north_of_home(beat: dict) -> float:
    return (beat["position"]["lat"] - HOME[0]) * 111_195.0


@BOTH
def test_take_off_above_the_gears_limit_is_refused_by_the_drone(windy, autopilot):
    ground, _ = windy(12.0)
    wind = ground.on("heartbeats")[-1]["wind"]
    assert wind["limit"] == LIMIT and wind["speed"] == pytest.approx(12.0, abs=0.05)
    assert wind["source"] == ("WIND_COV" if autopilot == "px4" else "WIND")
    assert ground.command("arm")["ok"]
    reply = ground.command("takeoff", altitude=10)
    assert not reply["ok"]
    assert "Wind 12.0 m/s" in reply["error"] and "limit of 8 m/s" in reply["error"]
    # A mission's take-off step is refused the same way: the mission does not fly.
    steps = [
        {"index": 0, "command": "arm", "params": {}},
        {"index": 1, "command": "takeoff", "params": {"altitude": 8}},
        {"index": 2, "command": "land", "params": {}},
    ]
    ground.send("mission", protocol.mission_start("WM1", "WA1", steps).to_dict())
    ended = ground.wait_for(
        "mission",
        lambda m: m.get("type") == "mission" and m["status"] in ("completed", "stopped", "failed"),
        20,
    )
    assert ended["status"] != "completed"
    failed = [m for m in ground.on("mission") if m.get("type") == "step" and m.get("index") == 1]
    assert failed and "Wind 12.0 m/s" in json.dumps(failed[-1]), json.dumps(ground.on("mission"))
    assert not any(b["airborne"] for b in ground.on("heartbeats"))


@BOTH
def test_wind_rising_above_the_limit_in_flight_returns_the_drone(windy):
    ground, wind_file = windy(4.0)
    assert ground.command("arm")["ok"]
    assert ground.command("takeoff", altitude=10)["ok"]
    assert ground.command("changeN", value=40)["ok"]
    ground.wait_for("heartbeats", lambda m: m["airborne"] and north_of_home(m) > 35, 20)
    raised = time.time()
    write_wind(wind_file, 12.0, 270.0)
    beat = ground.wait_for(
        "heartbeats", lambda m: (m.get("wind") or {}).get("action") == "return", 20
    )
    assert beat["wind"]["speed"] > LIMIT and beat["wind"]["since"] >= raised - 1
    # Home and on the ground, disarmed.
    ground.wait_for(
        "heartbeats",
        lambda m: (
            m["ts"] > raised
            and not m["armed"]
            and abs(north_of_home(m)) < 5
            and m["position"]["alt"] < 0.5
        ),
        40,
    )


@BOTH
def test_below_the_limit_the_drone_flies_normally(windy):
    ground, _ = windy(6.0)
    assert ground.command("arm")["ok"]
    assert ground.command("takeoff", altitude=10)["ok"]
    assert ground.command("changeN", value=30)["ok"]
    ground.wait_for("heartbeats", lambda m: m["airborne"] and north_of_home(m) > 28, 20)
    time.sleep(0.5)  # 10 flight seconds: more than the hold time
    beats = ground.on("heartbeats")
    assert all("action" not in (b.get("wind") or {}) for b in beats)
    assert math.isclose(beats[-1]["wind"]["speed"], 6.0, abs_tol=0.05)
    assert beats[-1]["airborne"] and north_of_home(beats[-1]) > 25
