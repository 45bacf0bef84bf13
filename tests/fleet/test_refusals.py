"""Refusing what storage cannot take, per message: the parsers' reasons, heartbeat batches
the database refuses, and the bounded per-drone counts on the status page."""

from __future__ import annotations

import json
import math
import time

import pytest

from fleet.heartbeats import handle_gear, handle_heartbeats
from fleet.models import Drone
from onboard import protocol
from workers import counters as counters_module
from workers.counters import OTHER_DRONES, REFUSAL_DRONES_KEY, REFUSALS_KEY, Counters, refusals

from .conftest import heartbeat

NOW = time.time()
HUGE = "x" * 200_000
# Our own Redis database, so the per-drone counts of other suites stay out of it.
REDIS_DB = 13


def _json(message: dict) -> bytes:
    # json.dumps writes float nan and inf as the bare NaN and Infinity a sloppy sender
    # would: editing the encoded text instead could also hit the digits of the message's
    # own time and make it not JSON at all.
    return json.dumps(message).encode()


_STEP = {"type": "step", "mission_id": "7", "index": 0, "command": "arm", "status": "started"}
_ALARM = {"type": "alarm", "level": "CRITICAL", "message": "hot", "ts": NOW}
_GEAR = {"type": "gear", "specs": {}, "sensors": {}, "ts": NOW}
POISON = [
    ("heartbeats", _json(heartbeat("D1", flight_mode="A\x00")), "bad_text", "flight_mode"),
    ("heartbeats", _json(heartbeat("D1", flight_mode="\ud800")), "bad_text", "flight_mode"),
    ("heartbeats", _json(heartbeat("D1", flight_mode=HUGE)), "too_long", "flight_mode"),
    (
        "heartbeats",
        _json(heartbeat("D1", battery={"voltage": math.nan, "remaining": 0.9})),
        "not_finite",
        "battery.voltage",
    ),
    ("heartbeats", _json(heartbeat("D1", ts=1e30)), "bad_timestamp", "ts"),
    ("heartbeats", _json(heartbeat("D1", ts=-1.0)), "bad_timestamp", "ts"),
    ("heartbeats", _json(heartbeat("D1", ts=10**400)), "not_finite", "ts"),
    ("mission", _json(_STEP | {"ts": NOW, "error": "\x00"}), "bad_text", "error"),
    (
        "mission",
        _json(_STEP | {"ts": NOW, "result": {"k": [{"\x00": 1}]}}),
        "bad_text",
        "result.k[0] key",
    ),
    (
        "mission",
        _json(_STEP | {"ts": NOW, "result": {"a": math.inf}}),
        "not_finite",
        "result.a",
    ),
    ("mission", _json(_STEP | {"ts": 1e30}), "bad_timestamp", "ts"),
    ("alarms", _json(_ALARM | {"sensor": HUGE}), "too_long", "sensor"),
    ("alarms", _json(_ALARM | {"ts": 1e30}), "bad_timestamp", "ts"),
    ("gear", _json(_GEAR | {"specs": {"TYPE": "HEXA\x00"}}), "bad_text", "specs.TYPE"),
    ("gear", _json(_GEAR | {"sensors": {"GAS": {"CO2": HUGE}}}), "too_long", "sensors.GAS.CO2"),
    ("pictures", _json({"name": "\ud800.jpg", "jpeg": "", "ts": NOW}), "bad_text", "name"),
]


# Ids without the payloads: these carry the collection time, and parallel workers
# (pytest-xdist) must collect the same test names.
@pytest.mark.parametrize(
    ("channel", "payload", "reason", "field"),
    POISON,
    ids=[f"{channel}-{reason}-{field}" for channel, _, reason, field in POISON],
)
def test_every_channel_refuses_what_storage_cannot_take_naming_field_and_reason(
    channel, payload, reason, field
):
    with pytest.raises(protocol.ProtocolError) as refused:
        protocol.parse_message(f"D1/{channel}/out", payload)
    assert (refused.value.reason, refused.value.field) == (reason, field)


def test_a_deeply_nested_result_is_refused():
    deep: dict = {}
    for _ in range(protocol.MAX_DEPTH + 1):
        deep = {"a": deep}
    with pytest.raises(protocol.ProtocolError, match="deeper"):
        protocol.parse_message("D1/mission/out", _json(_STEP | {"ts": NOW, "result": deep}))


def test_ordinary_text_and_times_still_pass():
    payload = _json(heartbeat("D1", flight_mode="Höhe ✈", ts=NOW))
    assert protocol.parse_message("D1/heartbeats/out", payload)[2].flight_mode == "Höhe ✈"


@pytest.mark.django_db(transaction=True)
@pytest.mark.parametrize("text", ["A\x00", "\udc00"])
def test_a_heartbeat_the_database_refuses_costs_only_its_own_drone(world_tx, text):
    """A heartbeat that validation would have refused, handed straight to the batch: the
    UPDATE is split until it alone is left out."""
    good, bad = world_tx.drone, world_tx.other_drone
    ok = protocol.parse_heartbeat(heartbeat(good.drone_id, flight_mode="LOITER"))
    poisoned = protocol.Heartbeat(**{**vars(ok), "drone_id": bad.drone_id, "flight_mode": text})
    reasons = handle_heartbeats([(bad.drone_id, poisoned), (good.drone_id, ok)])
    assert reasons == ["db_rejected", None]
    stored = Drone.objects.get(pk=good.pk)
    assert stored.online and stored.flight_mode == "LOITER"
    assert not Drone.objects.get(pk=bad.pk).online


@pytest.mark.django_db(transaction=True)
@pytest.mark.parametrize("text", ["A\x00", "\ud800"])
def test_gear_the_database_refuses_is_dropped_with_a_reason(world_tx, text):
    gear = protocol.GearAnnouncement(specs={"TYPE": "HEXA"}, sensors={"GAS": {"CO2": text}})
    assert handle_gear(world_tx.drone.drone_id, gear) == "db_rejected"
    assert Drone.objects.get(pk=world_tx.drone.pk).sensors == {}


@pytest.fixture
def own_redis(settings):  # type: ignore[no-untyped-def]
    from tests.missions.conftest import redis_url_with_db

    settings.REDIS_URL = redis_url_with_db(settings.REDIS_URL, REDIS_DB)
    client = counters_module._client()
    client.delete(REFUSALS_KEY, REFUSAL_DRONES_KEY)
    return client


def test_per_drone_counts_keep_at_most_the_cap_of_drone_ids(own_redis, settings):
    settings.REFUSAL_DRONES = 3
    first, second = Counters("gateway-refusals-a"), Counters("ingest-refusals-b")
    for i in range(5):
        first.refused(f"D{i}", "heartbeats.bad_text")
    first.flush()
    second.refused("D0", "telemetry.bad_text", 4)
    second.refused("D9", "telemetry.bad_value")
    second.flush()

    rows = {row["drone_id"]: row["reasons"] for row in refusals()}
    assert rows == {
        "D0": {"heartbeats.bad_text": 1, "telemetry.bad_text": 4},
        "D1": {"heartbeats.bad_text": 1},
        "D2": {"heartbeats.bad_text": 1},
        OTHER_DRONES: {"heartbeats.bad_text": 2, "telemetry.bad_value": 1},
    }
    assert own_redis.scard(REFUSAL_DRONES_KEY) == 3
    assert refusals()[0]["drone_id"] == "D0"  # the most refused first


@pytest.mark.django_db(transaction=True)
def test_the_status_page_shows_refusals_of_the_users_own_drones(world_tx, own_redis, client):
    counts = Counters("gateway-refusals-page")
    counts.refused(world_tx.drone.drone_id, "heartbeats.bad_text", 3)
    counts.refused(world_tx.other_drone.drone_id, "telemetry.ts_window", 5)
    counts.flush()

    client.force_login(world_tx.owner)
    page = client.get("/telemetry/status/").content.decode()
    assert "heartbeats.bad_text 3" in page and world_tx.drone.drone_id in page
    assert "telemetry.ts_window" not in page  # another organisation's drone
    client.force_login(world_tx.outsider)
    page = client.get("/telemetry/status/").content.decode()
    assert "telemetry.ts_window 5" in page and "heartbeats.bad_text" not in page
