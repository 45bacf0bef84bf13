"""Commands over the web process's own broker connection (workers.direct), and the outbox
taking over when that connection cannot deliver, on a real broker, gateway and drone."""

from __future__ import annotations

import asyncio
import json
import os
import signal
import socket
import threading
import time
from datetime import timedelta

import pytest
from asgiref.sync import async_to_sync
from django.db.models.signals import post_save

from fleet import commands
from fleet.models import CommandLog, Drone
from onboard import protocol
from runtime.processes import wait_for
from workers import direct, outbox

from .conftest import (
    GROUND_PASSWORD,
    Responder,
    client_for,
    drone_url,
    mqtt_client,
    subscribe_acked,
)

pytestmark = pytest.mark.django_db(transaction=True)


@pytest.fixture
def drone(responding_drone):  # type: ignore[no-untyped-def]
    return responding_drone


def _request(command: str = "arm") -> dict:
    return protocol.ControlRequest(protocol.new_request_id(), command, {}).to_dict()


def test_a_command_goes_direct_and_its_reply_comes_back_without_a_gateway(
    world_tx, broker, fresh_redis, ready_link, drone
):
    # No gateway runs: only the direct connection can carry the request and the reply.
    request = _request()
    reply = async_to_sync(direct.arequest)("ACME_1", "control", request, timeout=5)
    assert reply is not None and reply["ok"] is True
    assert reply["request_id"] == request["request_id"]
    assert [r["request_id"] for r in drone.requests] == [request["request_id"]]
    assert fresh_redis.llen(outbox.outbox_key()) == 0


def test_the_api_answers_with_the_reply_and_logs_it(world_tx, broker, gateway, ready_link, drone):
    published = gateway.counters.get("published")
    response = client_for(world_tx.operator).post(
        "/api/v1/drones/ACME_1/commands/",
        {"command": "arm", "params": {}},
        content_type="application/json",
    )
    assert response.status_code == 200, response.content
    body = response.json()
    assert body["ok"] is True and body["result"] == {"echo": {}}
    entry = CommandLog.objects.get(request_id=body["request_id"])
    assert (entry.command, entry.outcome, entry.user) == ("arm", "ok", world_tx.operator)
    assert entry.response["request_id"] == body["request_id"] and entry.answered_at
    assert gateway.counters.get("published") == published  # not through the outbox


def test_a_quick_answer_is_logged_once_with_its_outcome(world_tx, broker, ready_link, drone):
    saves: list[tuple[bool, str]] = []

    def saved(sender, instance, created, **kwargs):  # type: ignore[no-untyped-def]
        saves.append((created, instance.outcome))

    post_save.connect(saved, sender=CommandLog, dispatch_uid="test-quick-answer")
    try:
        outcome = async_to_sync(commands.send)(world_tx.operator, "ACME_1", "arm", {})
    finally:
        post_save.disconnect(dispatch_uid="test-quick-answer", sender=CommandLog)
    assert outcome.ok
    assert saves == [(True, "ok")]  # one write, its outcome in it: no pending row first
    entry = CommandLog.objects.get(request_id=outcome.request_id)
    assert entry.sent_at <= entry.answered_at  # type: ignore[operator]


def test_a_slow_answer_is_in_the_log_as_pending_while_it_travels(
    world_tx, broker, ready_link, settings
):
    settings.COMMAND_LOG_PENDING_AFTER_S = 0.1
    Drone.objects.filter(drone_id="ACME_1").update(online=True)
    slow = Responder(drone_url(broker, "ACME_1"), "ACME_1", delay=3.0)
    result: dict = {}

    def send() -> None:
        result["outcome"] = async_to_sync(commands.send)(world_tx.operator, "ACME_1", "arm", {})

    sender = threading.Thread(target=send)
    began = time.monotonic()
    sender.start()
    try:
        pending = CommandLog.objects.filter(drone__drone_id="ACME_1", outcome="pending")
        assert wait_for(pending.exists, 2.5), "no pending entry while the drone takes its time"
        # Before the answer (at 3 s), not with it: measured 0.16-0.17 s, quiet or loaded.
        assert time.monotonic() - began < 3.0
        sender.join(10)
    finally:
        slow.stop()
    entry = CommandLog.objects.get(request_id=result["outcome"].request_id)
    assert entry.outcome == "ok" and entry.answered_at - entry.sent_at >= timedelta(seconds=2.9)


def test_without_a_broker_connection_the_outbox_delivers(
    world_tx, broker, gateway, drone, settings
):
    # The gateway keeps its own (good) account; this process's connection is refused.
    direct.close()
    settings.MQTT_URL = broker.url_for("ground").replace(GROUND_PASSWORD, "wrong")
    link = direct.link()
    assert link is not None and not link.ready.wait(0.5)
    outcome = async_to_sync(commands.send)(world_tx.operator, "ACME_1", "arm", {})
    assert outcome.ok and outcome.reply["request_id"] == outcome.request_id  # type: ignore[index]
    assert gateway.counters.get("published") == 1
    entry = CommandLog.objects.get(request_id=outcome.request_id)
    assert entry.outcome == "ok" and entry.response["ok"] is True
    direct.close()


def test_a_publish_the_broker_does_not_acknowledge_in_time_also_goes_through_the_outbox(
    world_tx, broker, gateway, ready_link, drone, settings, fresh_redis
):
    settings.COMMAND_DIRECT_PUBACK_S = 0.3
    result: dict = {}

    def send() -> None:
        result["outcome"] = async_to_sync(commands.send)(world_tx.operator, "ACME_1", "arm", {})

    def queued() -> bool:
        waiting = fresh_redis.llen(outbox.outbox_key()) + fresh_redis.llen(gateway.taken)
        return waiting > 0

    sender = threading.Thread(target=send)
    os.kill(broker.process.pid, signal.SIGSTOP)  # connected, but acknowledging nothing
    try:
        sender.start()
        assert wait_for(queued, 5), "not handed to the outbox"
    finally:
        os.kill(broker.process.pid, signal.SIGCONT)
    sender.join(20)
    outcome = result["outcome"]
    assert outcome.ok
    # Both copies reach the drone under one request id (a drone ignores the repeat).
    assert wait_for(lambda: len(drone.requests) == 2, 5)
    assert {r["request_id"] for r in drone.requests} == {outcome.request_id}
    assert CommandLog.objects.get(request_id=outcome.request_id).outcome == "ok"


def test_a_reply_from_another_drone_is_not_taken(world_tx, broker, fresh_redis, ready_link):
    Drone.objects.filter(drone_id__in=["ACME_1", "GLOBEX_1"]).update(online=True)
    asked = mqtt_client(drone_url(broker, "ACME_1"))
    other = mqtt_client(drone_url(broker, "GLOBEX_1"))
    request = _request()

    def impostor(client, userdata, message):  # type: ignore[no-untyped-def]
        body = {**request, "ok": True, "result": {}, "error": None, "ts": time.time()}
        other.publish("GLOBEX_1/control/out", json.dumps(body), qos=1)

    asked.on_message = impostor
    subscribe_acked(asked, "ACME_1/control/in")
    try:
        reply = async_to_sync(direct.arequest)("ACME_1", "control", request, timeout=1.0)
    finally:
        for client in (asked, other):
            client.disconnect()
            client.loop_stop()
    assert reply is None


def test_a_reply_arriving_after_the_connection_is_lost_comes_through_redis(
    world_tx, broker, gateway, ready_link
):
    Drone.objects.filter(drone_id="ACME_1").update(online=True)
    drone = mqtt_client(drone_url(broker, "ACME_1"))
    asked = threading.Event()

    def answer_late(client, userdata, message):  # type: ignore[no-untyped-def]
        request = json.loads(message.payload)
        asked.set()
        time.sleep(0.5)  # meanwhile the web process loses its connection
        body = {**request, "ok": True, "result": {"late": True}, "error": None}
        client.publish("ACME_1/control/out", json.dumps(body), qos=1)

    drone.on_message = answer_late
    subscribe_acked(drone, "ACME_1/control/in")

    async def scenario() -> dict | None:
        pending = asyncio.ensure_future(direct.arequest("ACME_1", "control", _request(), timeout=5))
        await asyncio.to_thread(asked.wait, 5)
        ready_link.client.disconnect()
        return await pending

    try:
        reply = async_to_sync(scenario)()
    finally:
        drone.disconnect()
        drone.loop_stop()
    assert reply is not None and reply["result"] == {"late": True}


def test_a_lost_connection_with_a_waiter_of_a_closed_event_loop_still_reconnects(
    world_tx, broker, fresh_redis, ready_link, drone
):
    # A waiter left by an event loop that has ended (a finished test's, a stopped
    # server's): losing the connection resolves it, which must not end paho's thread.
    loop = asyncio.new_event_loop()

    async def abandoned() -> None:
        ready_link.expect(protocol.new_request_id(), "ACME_1")

    loop.run_until_complete(abandoned())
    loop.close()
    ready_link.client.socket().shutdown(socket.SHUT_RDWR)
    assert wait_for(lambda: not ready_link.ready.is_set(), 5), "the loss was not noticed"
    assert ready_link.ready.wait(10), "the connection did not come back"
    # No gateway runs: the reply can only come back over the connection that returned.
    request = _request()
    reply = async_to_sync(direct.arequest)("ACME_1", "control", request, timeout=5)
    assert reply is not None and reply["request_id"] == request["request_id"]
