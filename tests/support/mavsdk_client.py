"""MAVSDK flies a vehicle: arm, take off, go to a point, fly a mission, return to launch.

Run as `python tests/support/mavsdk_client.py PLAN_JSON`; PLAN_JSON is
{"url": "serial:///dev/pts/3:57600", "takeoff_alt": 10, "goto": [lat, lon, alt_amsl],
 "mission": [[lat, lon, alt_above_home], ...], "timeout": 20}.
Every phase prints one JSON line ({"phase": ..., ...}); any failure prints
{"error": ...} and exits 1. MAVSDK (the `mavsdk` wheel) calls its bundled C++ library in
this process: no server binary, nothing fetched. A test-only client, kept out of product
code; its own process, so a native crash or hang cannot take the test runner with it.
"""

from __future__ import annotations

import json
import math
import sys
import time
from collections.abc import Callable
from typing import Any

from mavsdk import ComponentType, Configuration, Mavsdk
from mavsdk.plugins.action import Action
from mavsdk.plugins.mission import Mission, MissionItem, MissionPlan
from mavsdk.plugins.telemetry import LandedState, Telemetry


def report(phase: str, **values: Any) -> None:
    print(json.dumps({"phase": phase, **values}), flush=True)


def until(what: str, predicate: Callable[[], Any], timeout: float) -> Any:
    """Poll MAVSDK's telemetry until `predicate()` is truthy; fail naming `what`."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(0.05)
    raise TimeoutError(f"{what} did not happen within {timeout:g} s")


def near(telemetry: Telemetry, lat: float, lon: float, metres: float) -> bool:
    here = telemetry.position()
    north = math.radians(here.latitude_deg - lat) * 6_371_000
    east = math.radians(here.longitude_deg - lon) * 6_371_000 * math.cos(math.radians(lat))
    return math.hypot(north, east) < metres


def fly(system: Any, plan: dict) -> None:
    telemetry, action, mission = Telemetry(system), Action(system), Mission(system)
    timeout = plan["timeout"]
    health = until(
        "a global position and home",
        lambda: (h := telemetry.health()).is_global_position_ok and h.is_home_position_ok and h,
        timeout,
    )
    report("healthy", armable=health.is_armable)
    action.set_takeoff_altitude(plan["takeoff_alt"])  # PX4's MIS_TAKEOFF_ALT, by PARAM_SET
    action.arm()
    report("armed", armed=telemetry.armed())
    action.takeoff()
    until(
        "the climb",
        lambda: telemetry.position().relative_altitude_m > plan["takeoff_alt"] - 0.5,
        timeout,
    )
    until("in-air state", telemetry.in_air, timeout)
    report("took off", altitude=telemetry.position().relative_altitude_m)

    lat, lon, alt_amsl = plan["goto"]
    action.goto_location(lat, lon, alt_amsl, 0.0)
    until("arrival at the goto point", lambda: near(telemetry, lat, lon, 1.0), timeout)
    report("arrived", absolute_altitude=telemetry.position().absolute_altitude_m)

    items = [
        MissionItem(
            latitude_deg=lat,
            longitude_deg=lon,
            relative_altitude_m=alt,
            speed_m_s=5.0,
            is_fly_through=False,
            acceptance_radius_m=1.0,
        )
        for lat, lon, alt in plan["mission"]
    ]
    mission.set_return_to_launch_after_mission(False)
    mission.upload_mission(MissionPlan(items))
    report("uploaded", items=len(items))
    mission.start_mission()
    until("the end of the mission", mission.is_mission_finished, timeout * len(items))
    progress = mission.mission_progress()
    report("mission finished", current=progress.current, total=progress.total)

    action.return_to_launch()
    until("landing and disarming", lambda: not telemetry.armed(), timeout * 2)
    until("on-ground state", lambda: telemetry.landed_state() == LandedState.ON_GROUND, timeout)
    report("landed", altitude=telemetry.position().relative_altitude_m)


def main() -> int:
    plan = json.loads(sys.argv[1])
    sdk = Mavsdk(Configuration.create_with_component_type(ComponentType.GROUND_STATION))
    try:
        result = sdk.add_any_connection(plan["url"])
        if result.name != "SUCCESS":
            raise ConnectionError(f"MAVSDK could not open {plan['url']}: {result.name}")
        system = sdk.first_autopilot(plan["timeout"])
        if system is None:
            raise TimeoutError("no autopilot heartbeat")
        report("connected", version=sdk.version(), autopilot=system.autopilot_type().name)
        fly(system, plan)
    except Exception as exc:  # reported to the test, which names the phase that failed
        print(json.dumps({"error": f"{type(exc).__name__}: {exc}"}), flush=True)
        return 1
    finally:
        sdk.destroy()
    return 0


if __name__ == "__main__":
    sys.exit(main())
