"""The ground's wind rule (fleet/wind.py) on stored drones: the limit from the gear, the
wind from the last heartbeat, the refusal and the airworthiness reason; the heartbeat's
`wind` on the wire."""

from __future__ import annotations

import time

import pytest

from fleet import airworthiness, wind
from fleet.models import Drone
from onboard import protocol

pytestmark = pytest.mark.django_db


def windy(drone: Drone, speed: float, *, specs: dict | None = None, limit: float = 10.0) -> Drone:
    drone.specs = specs or {}
    drone.fc = {"protocol": "mavlink", "wind": {"north": 0.0, "east": speed, "down": 0.0,
                                                "speed": speed, "limit": limit}}  # fmt: skip
    drone.airborne = False
    return drone


def test_the_limit_is_the_gears_and_a_malformed_one_counts_as_none(world):
    drone = world.drone
    drone.specs = {"MAX_WIND_M_S": 12}
    assert wind.limit_of(drone) == 12.0
    drone.specs = {"MAX_WIND_M_S": -4}
    assert wind.limit_of(drone) == 10.0
    drone.specs = {}
    assert wind.limit_of(drone) == 10.0


def test_the_lower_of_the_gears_and_the_drones_own_limit_applies(world):
    drone = windy(world.drone, 9.0, specs={"MAX_WIND_M_S": 12}, limit=8.0)
    assert wind.effective_limit(drone) == 8.0
    assert "Wind 9.0 m/s" in wind.refusal(drone) and "limit of 8 m/s" in wind.refusal(drone)


def test_no_estimate_or_within_the_limit_refuses_nothing(world):
    drone = world.drone
    drone.fc = {"protocol": "uavtalk"}
    assert wind.refusal(drone) is None and wind.above_limit(drone) is None
    assert wind.view(drone) == {"known": False, "limit": 10.0}
    assert wind.refusal(windy(drone, 7.5)) is None


def test_a_drone_in_a_wind_above_its_limit_is_not_airworthy(world):
    drone = windy(world.drone, 14.0)
    Drone.objects.filter(pk=drone.pk).update(fc=drone.fc, specs={})
    verdict = airworthiness.verdict(Drone.objects.get(pk=drone.pk))
    assert not verdict.airworthy
    assert "wind 14.0 m/s above its limit of 10 m/s" in verdict.reasons


def beat(wind_field: object) -> dict:
    return {"type": "heartbeat", "drone_id": "ACME_1", "ts": time.time(), "wind": wind_field}


def test_the_heartbeats_wind_is_parsed_strictly():
    good = {"north": 1.0, "east": -12.0, "down": 0.0, "speed": 12.04, "limit": 8,
            "source": "WIND", "action": "return", "since": time.time()}  # fmt: skip
    parsed = protocol.parse_heartbeat(beat(good))
    assert parsed.wind.action == "return" and parsed.wind.limit == 8.0
    assert protocol.parse_heartbeat(parsed.to_dict()) == parsed
    assert protocol.parse_heartbeat(beat(None)).wind is None
    for field, value in (("speed", -1), ("north", 1e6), ("action", "explode"), ("limit", "x")):
        with pytest.raises(protocol.ProtocolError, match=f"wind.{field}"):
            protocol.parse_heartbeat(beat({**good, field: value}))
    with pytest.raises(protocol.ProtocolError, match="wind.speed"):
        protocol.parse_heartbeat(beat({"north": 0, "east": 0, "down": 0, "limit": 8}))
