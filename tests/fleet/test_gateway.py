"""The gateway and the Drone Identifier on a real broker, Redis and database."""

from __future__ import annotations

import json
import time
import uuid
from datetime import timedelta

import pytest
from django.contrib.auth.models import User
from django.utils import timezone

from fleet import credentials
from fleet.heartbeats import sweep_offline
from fleet.models import ConnectionEvent, Drone
from records.models import OpenFlight
from runtime.processes import wait_for
from workers.counters import Counters, snapshot
from workers.gateway import Gateway

from .conftest import client_for, heartbeat, mqtt_client, subscribe_acked

pytestmark = pytest.mark.django_db(transaction=True)


def _drone_client(broker, drone_id: str):  # type: ignore[no-untyped-def]
    creds = credentials.provision(drone_id)
    url = f"mqtt://{drone_id}:{creds.password}@127.0.0.1:{broker.port}"
    return mqtt_client(url)


def test_a_heartbeat_updates_the_drone_and_records_it_coming_online(world_tx, broker, gateway):
    client = _drone_client(broker, "ACME_1")
    client.publish("ACME_1/heartbeats/out", json.dumps(heartbeat("ACME_1")), qos=0)

    drone = wait_for(lambda: Drone.objects.filter(drone_id="ACME_1", online=True).first())
    assert drone is not None
    assert (drone.lat, drone.lon, drone.alt) == (40.6303, -8.6575, 12.0)
    assert drone.battery_remaining == 0.9 and drone.armed and drone.airborne
    assert drone.fc["protocol"] == "uavtalk" and drone.fc["connected"] is True
    assert drone.fc["clock_trusted"] is True  # the test's clock is the ground's
    client.publish(
        "ACME_1/heartbeats/out", json.dumps(heartbeat("ACME_1")), qos=1
    ).wait_for_publish()
    wait_for(lambda: gateway.counters.get("handled") >= 2 or None, 2)
    kinds = list(ConnectionEvent.objects.filter(drone=drone).values_list("kind", flat=True))
    assert kinds == ["online"]
    client.loop_stop()


def test_a_gear_announcement_stores_specs_and_sensors(world_tx, broker, gateway):
    client = _drone_client(broker, "ACME_1")
    gear = {
        "type": "gear",
        "specs": {"TYPE": "HEXACOPTER", "BATTERY": {"CELL_COUNT": 4}},
        "sensors": {"GAS": {"CO2": "Sensirion SCD30"}},
        "ts": time.time(),
    }
    client.publish("ACME_1/gear/out", json.dumps(gear), qos=1)
    drone = wait_for(lambda: Drone.objects.filter(drone_id="ACME_1").exclude(specs={}).first())
    assert drone.specs["TYPE"] == "HEXACOPTER"
    assert drone.sensors == {"GAS": {"CO2": "Sensirion SCD30"}}
    client.loop_stop()


BAD_INPUT = [
    ("ACME_1/heartbeats/out", b"{not json", "malformed"),
    ("ACME_1/heartbeats/out", json.dumps(heartbeat("ACME_1", armed="very")).encode(), "malformed"),
    (
        "ACME_1/heartbeats/out",
        json.dumps(heartbeat("ACME_1", position={"lat": 123, "lon": 0, "alt": 0})).encode(),
        "malformed",
    ),
    ("ACME_1/heartbeats/out", json.dumps(heartbeat("GLOBEX_1")).encode(), "drone_id_mismatch"),
    ("NOBODY_9/heartbeats/out", json.dumps(heartbeat("NOBODY_9")).encode(), "unknown_drone"),
    ("ACME_1/heartbeats/out", b"[" + b"1," * 200_000 + b"1]", "too_large"),
    ("ACME_1/heartbeats/out", b"\xff\xfe", "malformed"),
    ("ACME_1/gear/out", json.dumps({"type": "gear", "specs": []}).encode(), "malformed"),
    (
        "ACME_1/control/out",
        json.dumps(
            {"request_id": "a" * 32, "command": "arm", "ok": True, "ts": time.time()}
        ).encode(),
        "unexpected_reply",
    ),
]


def test_malformed_and_unauthorised_input_is_dropped_counted_and_changes_nothing(
    world_tx, broker, gateway
):
    before = Drone.objects.get(drone_id="ACME_1")
    ground = mqtt_client(broker.url_for("ground"))
    for topic, payload, _reason in BAD_INPUT:
        ground.publish(topic, payload, qos=1).wait_for_publish()

    wait_for(lambda: gateway.counters.get("dropped") >= len(BAD_INPUT) or None)
    for _topic, _payload, reason in BAD_INPUT:
        assert gateway.counters.get(f"dropped.{reason}") >= 1, reason
    assert gateway.counters.get("dropped") == len(BAD_INPUT)
    after = Drone.objects.get(drone_id="ACME_1")
    assert (after.online, after.lat, after.specs, after.last_seen) == (
        before.online,
        before.lat,
        before.specs,
        before.last_seen,
    )
    assert not Drone.objects.filter(drone_id="NOBODY_9").exists()
    # The gateway is still serving, and its counts reach /health's process snapshot.
    assert gateway.client.is_connected()
    gateway.counters.flush()
    assert snapshot()[gateway.counters.process]["dropped.malformed"] >= 4
    staff = User.objects.create_user(f"operations-{uuid.uuid4().hex[:6]}", is_staff=True)
    health = client_for(staff).get("/health").json()  # the counters are for staff only
    assert health["processes"][gateway.counters.process]["dropped.too_large"] == 1
    ground.loop_stop()


def test_handlers_never_crash_the_gateway(world_tx, broker, fresh_redis):
    gw = Gateway(
        broker.url_for("ground"),
        dispatch={"heartbeats": "tests.fleet.test_gateway.explode_handler"},
        counters=Counters(f"gateway-test-{uuid.uuid4().hex[:8]}", flush_every=1e9),
    )
    gw.start()
    try:
        assert gw.wait_connected(5)
        ground = mqtt_client(broker.url_for("ground"))
        for _ in range(3):
            ground.publish("ACME_1/heartbeats/out", json.dumps(heartbeat("ACME_1")), qos=1)
        assert wait_for(lambda: gw.counters.get("dropped.handler_error") == 3 or None)
        assert gw.client.is_connected()
        ground.loop_stop()
    finally:
        gw.stop()


def explode_handler(drone_id: str, message: object) -> str | None:
    raise RuntimeError("bug in a handler")


def _backend_pids() -> set[int]:
    from django.db import connection

    with connection.cursor() as cursor:
        cursor.execute("SELECT pid FROM pg_stat_activity WHERE datname = current_database()")
        return {row[0] for row in cursor.fetchall()}


def _drop_other_database_sessions(keep: set[int]) -> int:
    """What a database restart or failover does to the gateway's connections: those
    opened since `keep` was read (this worker's other connections, which the tests after
    this one use, stay)."""
    from django.db import connection

    with connection.cursor() as cursor:
        cursor.execute(
            "SELECT count(pg_terminate_backend(pid)) FROM pg_stat_activity "
            "WHERE datname = current_database() AND pid <> pg_backend_pid() "
            "AND NOT (pid = ANY(%s))",
            [sorted(keep)],
        )
        return cursor.fetchone()[0]


def test_a_message_arriving_while_the_database_connection_is_lost_is_still_handled(
    world_tx, broker, gateway
):
    before = _backend_pids()
    client = _drone_client(broker, "ACME_1")

    def gear(kind: str) -> None:
        message = {"type": "gear", "specs": {"TYPE": kind}, "sensors": {}, "ts": time.time()}
        client.publish("ACME_1/gear/out", json.dumps(message), qos=1).wait_for_publish()

    # Both gateway threads hold an open connection: the handler's and the batch thread's.
    gear("QUAD")
    client.publish("ACME_1/heartbeats/out", json.dumps(heartbeat("ACME_1")), qos=1)
    assert wait_for(lambda: Drone.objects.filter(drone_id="ACME_1", online=True).exists())
    assert wait_for(lambda: Drone.objects.filter(specs__TYPE="QUAD").exists())
    # The batch thread is done with the first heartbeat, the armed drone's flight record
    # opened, before its connection goes (else that record would meet the loss first).
    assert wait_for(lambda: OpenFlight.objects.filter(drone__drone_id="ACME_1").exists())
    assert _drop_other_database_sessions(keep=before) >= 2

    gear("HEXACOPTER")
    later = heartbeat("ACME_1", battery={"voltage": 15.0, "remaining": 0.5})
    client.publish("ACME_1/heartbeats/out", json.dumps(later), qos=1).wait_for_publish()
    assert wait_for(lambda: Drone.objects.filter(specs__TYPE="HEXACOPTER").exists())
    assert wait_for(lambda: Drone.objects.filter(battery_remaining=0.5).exists())
    assert gateway.counters.get("db_retries") >= 2
    assert gateway.counters.get("dropped") == 0
    assert gateway.counters.get("dropped.handler_error") == 0
    client.loop_stop()


def test_a_drone_goes_offline_after_missed_heartbeats_and_comes_back_on_the_next(
    world_tx, broker, gateway, settings
):
    settings.HEARTBEAT_INTERVAL_S = 0.5
    ground = mqtt_client(broker.url_for("ground"))
    ground.publish("ACME_1/heartbeats/out", json.dumps(heartbeat("ACME_1")), qos=1)
    assert wait_for(lambda: Drone.objects.filter(drone_id="ACME_1", online=True).exists())

    assert sweep_offline() == []  # fresh: nothing to do
    later = timezone.now() + timedelta(seconds=1.6)
    assert sweep_offline(later) == ["ACME_1"]
    assert sweep_offline(later) == []  # compare-and-set: one offline event only
    drone = Drone.objects.get(drone_id="ACME_1")
    assert not drone.online

    ground.publish("ACME_1/heartbeats/out", json.dumps(heartbeat("ACME_1")), qos=1)
    assert wait_for(lambda: Drone.objects.filter(drone_id="ACME_1", online=True).exists())
    kinds = list(
        ConnectionEvent.objects.filter(drone=drone).order_by("pk").values_list("kind", flat=True)
    )
    assert kinds == ["online", "offline", "online"]
    ground.loop_stop()


def test_two_gateways_share_the_load_without_processing_a_message_twice(world_tx, broker, gateway):
    second = Gateway(
        broker.url_for("ground"),
        client_id="gw-second",
        counters=Counters(f"gateway-test-{uuid.uuid4().hex[:8]}", flush_every=1e9),
    )
    second.start()
    try:
        assert second.wait_connected(5)
        time.sleep(0.2)  # both subscriptions in place
        ground = mqtt_client(broker.url_for("ground"))
        for _ in range(40):
            ground.publish("ACME_1/heartbeats/out", json.dumps(heartbeat("ACME_1")), qos=1)

        def total() -> int:
            return gateway.counters.get("received") + second.counters.get("received")

        wait_for(lambda: total() >= 40 or None)
        time.sleep(0.3)
        assert total() == 40
        assert gateway.counters.get("received") > 0 and second.counters.get("received") > 0
        ground.loop_stop()
    finally:
        second.stop()


def test_the_gateway_reconnects_after_the_broker_restarts(world_tx, broker, gateway):
    broker.restart()
    assert wait_for(lambda: gateway.client.is_connected(), timeout=10)
    ground = mqtt_client(broker.url_for("ground"))
    ground.publish("ACME_1/heartbeats/out", json.dumps(heartbeat("ACME_1")), qos=1)
    assert wait_for(lambda: Drone.objects.filter(drone_id="ACME_1", online=True).exists(), 5)
    ground.loop_stop()


def test_outbox_messages_that_expired_are_not_sent(world_tx, broker, gateway):
    from workers import outbox

    received = []
    drone = _drone_client(broker, "ACME_1")
    drone.on_message = lambda c, u, m: received.append(json.loads(m.payload))
    subscribe_acked(drone, "ACME_1/control/in")
    outbox.send_to_drone("ACME_1", "control", {"stale": True}, ttl=-1)
    outbox.send_to_drone("ACME_1", "control", {"fresh": True}, ttl=10)
    assert wait_for(lambda: received)
    time.sleep(0.2)
    assert received == [{"fresh": True}]
    assert gateway.counters.get("outbox.expired") == 1
    drone.loop_stop()


def test_what_a_dead_gateway_had_taken_from_the_outbox_is_published_by_another(
    world_tx, broker, gateway
):
    """A gateway killed between taking a message and the broker's PUBACK leaves it on its
    taken list; once its heartbeat is gone a live gateway puts it back and sends it. A
    live peer's list is left alone, and what this gateway sends leaves none behind."""
    from workers import outbox
    from workers.counters import ALIVE_PREFIX

    received = []
    drone = _drone_client(broker, "ACME_1")
    drone.on_message = lambda c, u, m: received.append(json.loads(m.payload))
    subscribe_acked(drone, "ACME_1/control/in")
    client = outbox.sync_redis()

    def item(body: dict) -> bytes:
        return outbox.outbox_item("ACME_1", "control", body, ttl=30)

    dead = outbox.taken_key(gateway.outbox, "gateway:deadhost:1")
    busy = outbox.taken_key(gateway.outbox, "gateway:livehost:2")
    client.set(ALIVE_PREFIX + "gateway:livehost:2", 1, px=30_000)
    try:
        client.rpush(dead, item({"lost": True}))
        client.rpush(busy, item({"in_hand": True}))
        outbox.send_to_drone("ACME_1", "control", {"fresh": True}, ttl=10)
        assert wait_for(lambda: len(received) == 2, 10), received
        time.sleep(0.3)
        assert sorted(received, key=str) == [{"fresh": True}, {"lost": True}]
        assert gateway.counters.get("outbox.reclaimed") == 1
        assert client.llen(dead) == 0 and client.llen(gateway.taken) == 0
        assert client.llen(busy) == 1
        assert json.loads(client.lindex(busy, 0))["payload"] == {"in_hand": True}
    finally:
        client.delete(dead, busy, ALIVE_PREFIX + "gateway:livehost:2")
        drone.loop_stop()


def test_the_gateway_command_connects_and_drains_on_sigterm(broker, tmp_path):
    import os
    import signal
    import subprocess
    import sys

    from django.conf import settings as django_settings

    env = dict(
        os.environ,
        DJANGO_SETTINGS_MODULE="config.settings.test",
        TEST_WORKER_DB_NAME=django_settings.DATABASES["default"]["NAME"],
        PYTHONUNBUFFERED="1",
    )
    client_id = f"gateway-sigterm-test-{os.getpid()}"
    process = subprocess.Popen(
        [
            sys.executable,
            "manage.py",
            "gateway",
            "--broker",
            broker.url_for("ground"),
            "--client-id",
            client_id,
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        env=env,
        text=True,
    )
    try:
        # Other lines (a warning from a library under load) may come first: read until the
        # connection is reported or the process ends.
        lines: list[str] = []
        while not any("connected to 127.0.0.1" in line for line in lines):
            line = process.stdout.readline()
            assert line, lines
            lines.append(line)
        process.send_signal(signal.SIGTERM)
        # stop() gives each of its stages up to 5 s (outbox, lanes, batch thread): 30 s
        # holds all of them with room for a loaded machine.
        output, _ = process.communicate(timeout=30)
    finally:
        if process.poll() is None:
            process.kill()
        # The gateway's session is persistent and keeps its share of `$share` replies on the
        # broker this module shares with later tests: end the session as an operator would.
        _end_session(broker.url_for("ground"), client_id)
    assert process.returncode == 0
    assert "gateway: stopped" in output


def _end_session(url: str, client_id: str) -> None:
    """Connect once with a clean session under `client_id`, which discards the old one."""
    from .conftest import mqtt_client

    client = mqtt_client(url, client_id=client_id)
    client.disconnect()
    client.loop_stop()


def test_a_batch_of_heartbeats_is_one_update_keeping_each_drones_newest(world_tx):
    from django.db import connection
    from django.test.utils import CaptureQueriesContext

    from fleet.heartbeats import handle_heartbeats
    from onboard.protocol import parse_heartbeat

    def beat(drone_id: str, lat: float, sender: str | None = None):  # type: ignore[no-untyped-def]
        position = {"lat": lat, "lon": 0.0, "alt": 0.0}
        return (sender or drone_id, parse_heartbeat(heartbeat(drone_id, position=position)))

    batch = [
        beat("ACME_1", 1.0),
        beat("GLOBEX_1", 2.0),
        beat("ACME_1", 3.0),
        beat("NOBODY_9", 4.0),
        beat("GLOBEX_1", 5.0, sender="ACME_1"),
    ]
    with CaptureQueriesContext(connection) as queries:
        reasons = handle_heartbeats(batch)
    assert reasons == [None, None, None, "unknown_drone", "drone_id_mismatch"]
    updates = [q for q in queries.captured_queries if "UPDATE fleet_drone" in q["sql"]]
    assert len(updates) == 1
    assert Drone.objects.get(drone_id="ACME_1").lat == 3.0
    assert Drone.objects.get(drone_id="GLOBEX_1").lat == 2.0
    assert ConnectionEvent.objects.filter(kind="online").count() == 2


def test_the_place_a_drone_last_stood_on_the_ground_is_its_home_once_it_flies(world_tx):
    from fleet.envelopes import home_of
    from fleet.heartbeats import handle_heartbeats
    from onboard.protocol import parse_heartbeat

    def beat(lat: float, alt: float, airborne: bool):  # type: ignore[no-untyped-def]
        position = {"lat": lat, "lon": 0.5, "alt": alt}
        message = heartbeat("ACME_1", position=position, armed=airborne, airborne=airborne)
        return [("ACME_1", parse_heartbeat(message))]

    handle_heartbeats(beat(1.0, 0.0, False))
    handle_heartbeats(beat(1.001, 0.0, False))  # carried to another field: a new home
    handle_heartbeats(beat(1.002, 12.0, True))
    handle_heartbeats(beat(1.003, 15.0, True))
    drone = Drone.objects.get(drone_id="ACME_1")
    assert drone.home == [1.001, 0.5]
    assert home_of(drone) == (1.001, 0.5)


def test_the_offline_sweep_is_a_beat_task(world_tx, settings):
    from config.celery import app
    from fleet.tasks import sweep_offline_drones

    schedule = settings.CELERY_BEAT_SCHEDULE["fleet.sweep_offline"]
    assert schedule["task"] == "fleet.sweep_offline" == sweep_offline_drones.name
    assert schedule["schedule"] <= settings.HEARTBEAT_INTERVAL_S
    assert "fleet.sweep_offline" in app.tasks
    stale = timezone.now() - timedelta(seconds=60)
    Drone.objects.filter(drone_id="ACME_1").update(online=True, last_seen=stale)
    assert sweep_offline_drones.apply().get() == ["ACME_1"]
    assert ConnectionEvent.objects.get(drone__drone_id="ACME_1").kind == "offline"
