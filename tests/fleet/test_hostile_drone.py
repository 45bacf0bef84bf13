"""A hostile drone beside a good one, on a real broker, gateway, ingest, database and Redis:
everything the hostile one sends that storage cannot take is refused per message and
counted against it, and every sample, heartbeat and step report of the good one lands."""

from __future__ import annotations

import json
import math
import time
import uuid
from collections import Counter
from typing import Any

import psycopg
import pytest
from django.utils import timezone

from fleet.heartbeats import sweep_offline
from fleet.models import Drone
from missions.creation import create_mission
from missions.models import Mission, MissionStatus, StepStatus
from missions.startstop import start_mission
from runtime.processes import wait_for
from telemetry.ingest import DroneMap, IngestConfig, Ingestor, load_drone_ids
from telemetry.queries import conninfo_from_settings
from workers import outbox
from workers.counters import REFUSAL_DRONES_KEY, REFUSALS_KEY, Counters, refusals
from workers.gateway import Gateway
from workers.mosquitto import start_broker

from ..telemetry.support import drone_messages
from .conftest import heartbeat, mqtt_client

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]

# A Redis database of our own: the per-drone refusals of other suites stay out of it.
REDIS_DB = 12
DRONES = ("ACME_1", "GLOBEX_1")
HUGE = "x" * 200_000
STEPS = [
    {"command": "arm"},
    {"command": "takeoff", "params": {"altitude": 10}},
    {"command": "land"},
]


@pytest.fixture
def broker(tmp_path):  # type: ignore[no-untyped-def]
    """A broker of our own: no session a stopped gateway left on the shared one takes a
    share of the messages."""
    users = {"ground": "ground-pw", **{drone_id: f"{drone_id}-pw" for drone_id in DRONES}}
    b = start_broker(tmp_path, users)
    yield b
    b.stop()


@pytest.fixture
def own_redis(settings, broker):  # type: ignore[no-untyped-def]
    from tests.missions.conftest import redis_url_with_db

    settings.REDIS_URL = redis_url_with_db(settings.REDIS_URL, REDIS_DB)
    settings.MQTT_URL = broker.url_for("ground")  # the mission start goes to our gateway
    outbox._sync_client = None
    client = outbox.sync_redis()
    client.delete(REFUSALS_KEY, REFUSAL_DRONES_KEY, outbox.outbox_key(broker.url))
    yield client
    outbox._sync_client = None


@pytest.fixture
def ground(broker, own_redis):  # type: ignore[no-untyped-def]
    """The gateway and the ingest, both counting into Redis every 0.2 s."""
    conninfo = conninfo_from_settings()
    gateway = Gateway(
        broker.url_for("ground"),
        client_id=f"gw-{uuid.uuid4().hex[:8]}",
        counters=Counters(f"gateway-test-{uuid.uuid4().hex[:8]}", flush_every=0.2),
    )
    ingest = Ingestor(
        IngestConfig(conninfo=conninfo, mqtt_url=broker.url_for("ground"), flush_interval=0.05),
        drones=DroneMap(lambda: load_drone_ids(conninfo)),
        counters=Counters(f"ingest-test-{uuid.uuid4().hex[:8]}", flush_every=0.2),
    )
    gateway.start()
    ingest.start()
    try:
        assert gateway.wait_connected(10)
        assert ingest.subscriber.subscribed.wait(10)
        yield gateway, ingest
    finally:
        ingest.stop()
        gateway.stop()


def _drone_client(broker, drone_id: str):  # type: ignore[no-untyped-def]
    return mqtt_client(broker.url_for(drone_id))


def _telemetry(now: float, fields: dict, ts: float | None = None) -> bytes:
    obj = {"name": "FlightStatus", "ts": now if ts is None else ts, "fields": fields}
    return json.dumps({"ts": now, "objects": [obj]}).encode()


def _hostile_messages(drone_id: str, mission_id: str, now: float) -> list[tuple[str, bytes, str]]:
    """(channel, payload, reason refused): NUL text, an unpaired surrogate, 200 kB strings,
    NaN and times of 1e30, on every channel the ground stores. NaN and Infinity come from
    json.dumps itself (it writes them for float nan/inf): editing the encoded bytes would
    also hit the clock's digits in "ts" whenever they hold the text replaced, and turn a
    non-finite value into a message that is not JSON at all."""
    beat = heartbeat(drone_id)
    step = {"type": "step", "mission_id": mission_id, "index": 0, "command": "arm"}
    step |= {"status": "failed", "ts": now}
    alarm = {"type": "alarm", "level": "CRITICAL", "message": "hot", "ts": now}
    return [
        ("telemetry", _telemetry(now, {"Armed": "Ar\x00med"}), "bad_text"),
        ("telemetry", _telemetry(now, {"Armed": "\ud800"}), "bad_text"),
        ("telemetry", _telemetry(now, {"Armed": HUGE}), "bad_value"),
        ("telemetry", _telemetry(now, {"Armed": math.nan}), "bad_value"),
        ("telemetry", _telemetry(now, {"Armed": 1}, ts=1e30), "ts_window"),
        ("heartbeats", json.dumps(beat | {"flight_mode": "HO\x00LD"}).encode(), "bad_text"),
        ("heartbeats", json.dumps(beat | {"flight_mode": HUGE}).encode(), "too_long"),
        ("heartbeats", json.dumps(beat | {"ts": 1e30}).encode(), "bad_timestamp"),
        (
            "heartbeats",
            json.dumps(beat | {"battery": {"voltage": math.nan, "remaining": 0.9}}).encode(),
            "not_finite",
        ),
        ("mission", json.dumps(step | {"error": "bad\x00"}).encode(), "bad_text"),
        ("mission", json.dumps(step | {"error": HUGE}).encode(), "too_long"),
        ("mission", json.dumps(step | {"ts": 1e30}).encode(), "bad_timestamp"),
        ("mission", json.dumps(step | {"duration_s": math.inf}).encode(), "not_finite"),
        ("alarms", json.dumps(alarm | {"message": "\x00"}).encode(), "bad_text"),
        (
            "gear",
            json.dumps({"type": "gear", "specs": {"A\x00": 1}, "sensors": {}, "ts": now}).encode(),
            "bad_text",
        ),
        ("pictures", json.dumps({"name": "p\x00.jpg", "jpeg": "", "ts": now}).encode(), "bad_text"),
    ]


@pytest.mark.parametrize("now", [1764731541.52, 1764731516.4, 1764731500.25])
def test_every_hostile_message_is_json_whatever_the_clock_reads(now):
    """Each message is refused for its content, never for not being JSON: clocks whose
    digits hold "1.5" or "16.4" once turned the NaN messages into broken JSON."""
    for channel, payload, reason in _hostile_messages("ACME_1", str(uuid.uuid4()), now):
        assert json.loads(payload), (channel, reason)


def _steps_done(mission) -> bool:  # type: ignore[no-untyped-def]
    statuses = set(mission.steps.values_list("status", flat=True))
    return statuses == {StepStatus.COMPLETED}


def _stored(drone_pk: int) -> int:
    with psycopg.connect(conninfo_from_settings()) as conn:
        query = "SELECT count(*) FROM telemetry_sample WHERE drone_id = %s"
        return conn.execute(query, (drone_pk,)).fetchone()[0]


def _started_mission(drone: Drone) -> tuple[str, str]:
    Drone.objects.filter(pk=drone.pk).update(
        online=True, last_seen=timezone.now(), battery_remaining=0.9
    )
    mission = create_mission(organisation=drone.organisation, name="survey", steps=STEPS)
    assignment = start_mission(mission, drone=drone).assignment
    return str(mission.pk), str(assignment.pk)


def _report_steps(client: Any, drone_id: str, mission_id: str, assignment_id: str) -> None:
    for index, step in enumerate(STEPS):
        for status in ("started", "completed"):
            report = {"type": "step", "mission_id": mission_id, "assignment_id": assignment_id}
            report |= {"index": index, "command": step["command"], "status": status}
            client.publish(
                f"{drone_id}/mission/out", json.dumps(report | {"ts": time.time()}), qos=1
            )


def test_a_hostile_drone_costs_the_good_drone_nothing(world_tx, broker, ground):
    gateway, ingest = ground
    good, hostile = world_tx.drone, world_tx.other_drone
    mission_id, assignment_id = _started_mission(good)
    good_client = _drone_client(broker, good.drone_id)
    hostile_client = _drone_client(broker, hostile.drone_id)
    before = Drone.objects.get(pk=hostile.pk)
    samples = list(drone_messages(time.time() - 20, seconds=20))
    attacks = _hostile_messages(hostile.drone_id, mission_id, time.time())
    for i, message in enumerate(samples):
        # Interleaved, so the good drone's messages share batches with the hostile ones.
        channel, payload, _reason = attacks[i % len(attacks)]
        hostile_client.publish(f"{hostile.drone_id}/{channel}/out", payload, qos=1)
        good_client.publish(f"{good.drone_id}/telemetry/out", json.dumps(message), qos=1)
        beat = heartbeat(good.drone_id, battery={"voltage": 16.0, "remaining": 0.5 + i / 1000})
        good_client.publish(f"{good.drone_id}/heartbeats/out", json.dumps(beat), qos=1)
    _report_steps(good_client, good.drone_id, mission_id, assignment_id)

    expected = sum(len(m["objects"]) for m in samples)
    assert wait_for(lambda: _stored(good.pk) >= expected, 30), (_stored(good.pk), expected)
    last = 0.5 + (len(samples) - 1) / 1000
    assert wait_for(lambda: Drone.objects.filter(pk=good.pk, battery_remaining=last).exists())
    mission = good.assignments.get(pk=assignment_id).mission
    assert wait_for(lambda: _steps_done(mission), 20)
    assert wait_for(lambda: Mission.objects.get(pk=mission.pk).status == MissionStatus.COMPLETED)
    assert _stored(good.pk) == expected and _stored(hostile.pk) == 0
    assert Drone.objects.get(pk=good.pk).online
    assert good.drone_id not in sweep_offline()  # its heartbeats kept it fresh

    # Nothing of the hostile drone's changed its row; every refusal counts against it alone.
    after = Drone.objects.get(pk=hostile.pk)
    assert (after.flight_mode, after.specs, after.last_seen) == (
        before.flight_mode,
        before.specs,
        before.last_seen,
    )
    sent = [attacks[i % len(attacks)] for i in range(len(samples))]
    expected_reasons = Counter(f"{channel}.{reason}" for channel, _payload, reason in sent)
    wait_for(lambda: _refused(hostile.drone_id).get("total", 0) >= len(sent), 10)
    assert _refused(hostile.drone_id)["reasons"] == dict(expected_reasons)
    assert _refused(good.drone_id) == {}
    good_client.loop_stop()
    hostile_client.loop_stop()


def _refused(drone_id: str) -> dict:
    return next((row for row in refusals() if row["drone_id"] == drone_id), {})
