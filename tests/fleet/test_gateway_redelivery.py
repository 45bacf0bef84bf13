"""A message the broker delivers again (its acknowledgement lost, a gateway restarted
with it in hand) is recorded once: step reports, mission statuses and alarms carry their
message key."""

from __future__ import annotations

import json
import time

import pytest

from missions.creation import create_mission
from missions.models import Event
from missions.startstop import start_mission
from runtime.processes import wait_for

from ..missions.conftest import online_drone
from .conftest import mqtt_client

pytestmark = pytest.mark.e2e


def test_the_same_step_report_status_and_alarm_twice_are_recorded_once(world_tx, broker, gateway):
    drone = online_drone(world_tx.org, "ACME_RD")
    mission = create_mission(
        organisation=world_tx.org, name="again", steps=[{"command": "arm"}, {"command": "land"}]
    )
    assignment = start_mission(mission, drone=drone).assignment
    ids = {"mission_id": str(mission.pk), "assignment_id": str(assignment.pk)}
    now = time.time()
    accepted = {"type": "mission", **ids, "status": "accepted", "decode_ms": 0.4, "ts": now}
    step = {"type": "step", **ids, "index": 0, "command": "arm", "status": "completed"}
    step |= {"ts": now + 1, "duration_s": 1.0, "result": {}, "error": None}
    alarm = {"type": "alarm", "level": "OUT_MEASURE", "message": "CO2 high", "ts": now + 2}
    alarm |= {**ids, "index": 0, "sensor": "CO2", "value": 900.0}
    ground = mqtt_client(broker.url_for("ground"))
    try:
        for _ in range(2):
            for channel, message in (("mission", accepted), ("mission", step), ("alarms", alarm)):
                info = ground.publish(f"ACME_RD/{channel}/out", json.dumps(message), qos=1)
                info.wait_for_publish(5)
        assert wait_for(lambda: gateway.counters.get("handled") >= 6 or None, 20)
        reported = [Event.Kind.MISSION, Event.Kind.STEP, Event.Kind.ALARM]
        kinds = mission.events.filter(drone=drone, kind__in=reported)
        assert sorted(kinds.values_list("kind", flat=True)) == sorted(reported)
        assert gateway.counters.get("dropped") == 0
    finally:
        ground.loop_stop()
