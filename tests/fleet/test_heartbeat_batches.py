"""Heartbeats in bursts: read by the gateway's own reader, stored many at once.

Whatever the batching, the outcome must be that of storing them one by one: each drone
shows its newest heartbeat, it came online once, every message is counted (refused ones
per drone and reason), and a message is acknowledged only once it is stored.
"""

from __future__ import annotations

import json
import threading
import time
import uuid

import pytest
from django.db import connection
from django.test.utils import CaptureQueriesContext

from fleet.models import ConnectionEvent, Drone
from runtime.processes import wait_for
from tests import factories
from workers.counters import Counters, refusals
from workers.dispatch import MAX_BATCH
from workers.gateway import Gateway
from workers.lanes import BatchQueue

from .conftest import heartbeat, mqtt_client
from .test_gateway import _drone_client

pytestmark = pytest.mark.django_db(transaction=True)

DRONES = ("ACME_1", "ACME_2", "GLOBEX_1")
ROUNDS = 40


def _beat(drone_id: str, i: int, **overrides: object) -> bytes:
    position = {"lat": 40.0 + i / 1000, "lon": -8.0, "alt": float(i)}
    mode = "AUTO" if i % 2 else "POSITIONHOLD"
    message = heartbeat(drone_id, position=position, flight_mode=mode, **overrides)
    return json.dumps(message).encode()


def _refused(drone_id: str) -> dict[str, int]:
    row = next((r for r in refusals() if r["drone_id"] == drone_id), None)
    return dict(row["reasons"]) if row else {}


def _idle_gateway(broker, **kwargs) -> Gateway:  # type: ignore[no-untyped-def]
    """Built, not started: the test plays its network thread, then its batch thread."""
    return Gateway(
        broker.url_for("ground"),
        client_id=f"gw-{uuid.uuid4().hex[:8]}",
        counters=Counters(f"gateway-test-{uuid.uuid4().hex[:8]}", flush_every=1e9),
        **kwargs,
    )


def test_a_burst_is_one_statement_storing_each_drones_newest_and_settled_after(
    world_tx, broker, fresh_redis
):
    factories.drone(world_tx.org, "ACME_2")
    gw = _idle_gateway(broker)
    seen_at_settle: list[tuple[str, float]] = []

    def settler(drone_id: str):  # type: ignore[no-untyped-def]
        def settle() -> None:
            stored = Drone.objects.filter(drone_id=drone_id, online=True).first()
            seen_at_settle.append((drone_id, stored.alt if stored else -1.0))

        return settle

    before = _refused("ACME_1")
    for i in range(ROUNDS):
        for drone_id in DRONES:
            gw._take_batched(f"{drone_id}/heartbeats/out", _beat(drone_id, i), settler(drone_id))
        if i == ROUNDS // 2:
            bad = _beat("ACME_1", i, armed="very")
            gw._take_batched("ACME_1/heartbeats/out", bad, settler("ACME_1"))
            other = _beat("GLOBEX_1", i)
            gw._take_batched("ACME_1/heartbeats/out", other, settler("ACME_1"))
    taken = gw._batch.take(MAX_BATCH, 0)
    # The malformed one never reaches the batch; the other drone's is refused in it.
    assert len(taken) == ROUNDS * len(DRONES) + 1
    with CaptureQueriesContext(connection) as queries:
        gw._run_batch(taken)
    updates = [q for q in queries.captured_queries if "UPDATE fleet_drone" in q["sql"]]
    assert len(updates) == 1

    last = float(ROUNDS - 1)
    for drone_id in DRONES:
        drone = Drone.objects.get(drone_id=drone_id)
        assert drone.online and drone.alt == last and drone.lat == pytest.approx(40.039)
        assert drone.flight_mode == "AUTO"  # the newest, not the first, of the burst
        kinds = ConnectionEvent.objects.filter(drone=drone).values_list("kind", flat=True)
        assert list(kinds) == ["online"]
    # Each message of the batch was settled once it was written; the malformed one at once.
    stored_settles = [alt for _d, alt in seen_at_settle if alt == last]
    assert len(stored_settles) == ROUNDS * len(DRONES) + 1
    assert seen_at_settle[0] == ("ACME_1", -1.0)
    assert len(seen_at_settle) == ROUNDS * len(DRONES) + 2

    counters = gw.counters
    assert counters.get("received") == ROUNDS * len(DRONES) + 2
    assert counters.get("handled") == ROUNDS * len(DRONES)
    assert counters.get("dropped") == 2
    assert counters.get("dropped.malformed") == counters.get("dropped.drone_id_mismatch") == 1
    counters.flush()
    after = _refused("ACME_1")
    for reason in ("heartbeats.malformed", "heartbeats.drone_id_mismatch"):
        assert after.get(reason, 0) - before.get(reason, 0) == 1, reason


def test_a_full_queue_drops_as_overload_counted_against_the_drone_and_settled(
    world_tx, broker, fresh_redis, monkeypatch
):
    import workers.gateway as gateway_module

    monkeypatch.setattr(gateway_module, "MAX_QUEUED", 3)
    gw = _idle_gateway(broker)
    gw._batch = BatchQueue(3)
    settled: list[int] = []
    for i in range(5):
        gw._take_batched("ACME_1/heartbeats/out", _beat("ACME_1", i), lambda i=i: settled.append(i))
    assert settled == [3, 4]  # dropped for good at once; the others once stored
    assert gw.counters.get("dropped.overload") == 2
    gw._run_batch(gw._batch.take(MAX_BATCH, 0))
    assert settled == [3, 4, 0, 1, 2]
    assert Drone.objects.get(drone_id="ACME_1").alt == 2.0


def test_a_burst_through_the_broker_ends_with_each_drones_newest_state(world_tx, broker, gateway):
    factories.drone(world_tx.org, "ACME_2")
    clients = {drone_id: _drone_client(broker, drone_id) for drone_id in DRONES}
    for i in range(ROUNDS):
        for drone_id, client in clients.items():
            client.publish(f"{drone_id}/heartbeats/out", _beat(drone_id, i), qos=0)
    clients["ACME_1"].publish("ACME_1/heartbeats/out", b"{not json", qos=0)
    total = ROUNDS * len(DRONES) + 1

    counters = gateway.counters
    assert wait_for(lambda: counters.get("received") >= total or None, 10)
    assert counters.get("handled") == total - 1 and counters.get("dropped.malformed") == 1
    last = float(ROUNDS - 1)
    for drone_id in DRONES:
        drone = Drone.objects.get(drone_id=drone_id)
        assert drone.online and drone.alt == last and drone.flight_mode == "AUTO"
        assert ConnectionEvent.objects.filter(drone=drone, kind="online").count() == 1
    for client in clients.values():
        client.loop_stop()


def test_a_failing_batch_handler_costs_its_batch_only_and_the_gateway_goes_on(
    world_tx, broker, fresh_redis
):
    gw = _idle_gateway(broker, batch_dispatch={"heartbeats": f"{__name__}.explode_batch"})
    gw.start()
    try:
        assert gw.wait_connected(10)
        ground = mqtt_client(broker.url_for("ground"))
        for i in range(3):
            ground.publish("ACME_1/heartbeats/out", _beat("ACME_1", i), qos=1)
        assert wait_for(lambda: gw.counters.get("dropped.handler_error") == 3 or None, 10)
        assert gw.counters.get("received") == 3 and gw.client.is_connected()
        ground.loop_stop()
    finally:
        gw.stop()


def explode_batch(batch: list) -> list:
    raise RuntimeError("bug in a batch handler")


def test_the_batch_queue_keeps_order_bounds_its_size_and_wakes_its_reader():
    q = BatchQueue(limit=4)
    assert [q.put(i) for i in range(5)] == [True, True, True, True, False]
    assert q.take(3, timeout=0) == [0, 1, 2]
    assert q.take(10, timeout=0) == [3]
    began = time.monotonic()
    assert q.take(10, timeout=0.05) == []
    assert time.monotonic() - began >= 0.04
    threading.Timer(0.05, q.put, args=("late",)).start()
    assert wait_for(lambda: q.take(10, timeout=1.0) or None, 2) == ["late"]


def test_a_parsed_heartbeat_is_the_one_its_constructor_builds():
    import dataclasses

    from onboard import protocol

    message = json.loads(_beat("ACME_1", 3))
    message["fc"]["setup"] = ["Set the receiver type"]
    parsed = protocol.parse_heartbeat(message)
    names = {f.name for f in dataclasses.fields(protocol.Heartbeat)}
    assert set(vars(parsed)) == names
    assert parsed == protocol.Heartbeat(**vars(parsed)) and hash(parsed)
    with pytest.raises(dataclasses.FrozenInstanceError):
        parsed.armed = False  # type: ignore[misc]
    assert parsed.to_dict()["fc"]["setup"] == ["Set the receiver type"]
