"""Alerts: raised once per happening by what the ground records, pushed to the
organisation's open pages only, and delivered to each recipient once, with retries."""

from __future__ import annotations

import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import pytest
from django.core import mail
from rest_framework.test import APIClient

from accounts.organisation import settings_of
from alerts import delivery
from alerts.models import Alert, Delivery
from alerts.tasks import deliver
from fleet.models import Drone
from fleet.signals import drones_went_offline
from missions.journal import record
from missions.models import Event, Mission, MissionStatus
from tests.support.websocket import connect_websocket


def _mission(org, status=MissionStatus.RUNNING) -> Mission:
    return Mission.objects.create(organisation=org, name="Campus survey", status=status)


def critical_alarm(org, drone, message: str) -> Event:  # type: ignore[no-untyped-def]
    """A CRITICAL alarm recorded on a running mission, as the gateway records one."""
    return record(
        _mission(org),
        Event.Kind.ALARM,
        "CRITICAL",
        drone=drone,
        data={"level": "CRITICAL", "message": message},
    )


def _recipients(org, *entries: str) -> None:
    stored = settings_of(org)
    stored.alert_recipients = list(entries)
    stored.save()


class Webhook:
    """A real HTTP endpoint that answers `codes` in turn (then 200) and keeps what it got."""

    def __init__(self, *codes: int) -> None:
        self.codes = list(codes)
        self.requests: list[tuple[dict, bytes]] = []
        hook = self

        class Handler(BaseHTTPRequestHandler):
            def do_POST(self) -> None:  # noqa: N802 - the http.server name
                body = self.rfile.read(int(self.headers["Content-Length"]))
                hook.requests.append((dict(self.headers), body))
                self.send_response(hook.codes.pop(0) if hook.codes else 200)
                self.end_headers()

            def log_message(self, *args: object) -> None:
                return

        self.server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        threading.Thread(target=self.server.serve_forever, daemon=True).start()
        self.url = f"http://127.0.0.1:{self.server.server_port}/hook"

    def close(self) -> None:
        self.server.shutdown()
        self.server.server_close()


@pytest.fixture
def webhook():  # type: ignore[no-untyped-def]
    hooks: list[Webhook] = []

    def make(*codes: int) -> Webhook:
        hooks.append(Webhook(*codes))
        return hooks[-1]

    yield make
    for hook in hooks:
        hook.close()


def test_a_critical_alarm_raises_one_alert_with_a_delivery_per_recipient(
    world, django_capture_on_commit_callbacks
):
    _recipients(world.org, "ops@example.org", "https://hooks.example.org/skyhive")
    mission = _mission(world.org)
    with django_capture_on_commit_callbacks():
        event = record(
            mission,
            Event.Kind.ALARM,
            "CRITICAL",
            drone=world.drone,
            data={"level": "CRITICAL", "message": "battery 18 %"},
        )
    alert = Alert.objects.get()
    assert alert.kind == Alert.Kind.CRITICAL_ALARM and alert.severity == "critical"
    assert "battery 18 %" in alert.title and alert.drone_id == "ACME_1"
    assert sorted(d.channel for d in alert.deliveries.all()) == ["email", "webhook"]
    event.save()  # the same event seen again raises nothing more
    assert Alert.objects.count() == 1


def test_an_out_measure_alarm_raises_no_alert(world):
    record(
        _mission(world.org),
        Event.Kind.ALARM,
        "OUT_MEASURE",
        drone=world.drone,
        data={"level": "OUT_MEASURE", "message": "CO2 high"},
    )
    assert not Alert.objects.exists()


def test_replacement_completion_failure_and_a_lost_drone_raise_alerts(world):
    mission = _mission(world.org)
    record(
        mission,
        Event.Kind.HANDOVER,
        "ACME_1 → ACME_2",
        data={"from": "ACME_1", "to": "ACME_2", "handed_over": [4, 5, 6], "reason": "replacement"},
    )
    Mission.objects.filter(pk=mission.pk).update(status=MissionStatus.COMPLETED)
    record(mission, Event.Kind.DECISION, "every step is completed", data={"decision": "completed"})
    failed = _mission(world.org, status=MissionStatus.FAILED)
    record(failed, Event.Kind.DECISION, "mission failed", data={"decision": "failed"})
    Drone.objects.filter(pk=world.drone.pk).update(online=False, airborne=True)
    drones_went_offline.send(sender=None, drone_ids=["ACME_1"])
    drones_went_offline.send(sender=None, drone_ids=["ACME_1"])  # the same loss, seen twice
    kinds = sorted(Alert.objects.values_list("kind", flat=True))
    assert kinds == ["drone_lost", "mission_completed", "mission_failed", "replacement"]
    assert Alert.objects.get(kind="replacement").title.startswith("ACME_1 replaced by ACME_2")
    assert Alert.objects.get(kind="drone_lost").detail == "It was airborne."


@pytest.mark.django_db(transaction=True)
def test_a_webhook_that_fails_first_gets_the_alert_once_after_a_retry(world_tx, webhook, settings):
    settings.ALERT_RETRY_BASE_S = 0
    settings.ALERT_WEBHOOK_ALLOW_PRIVATE = True  # the receiver is on loopback
    hook = webhook(500)
    _recipients(world_tx.org, hook.url)
    critical_alarm(world_tx.org, world_tx.drone, "motor failure")
    item = Delivery.objects.get()
    deliver.apply(args=[str(item.pk)])  # 500, then retried: 200
    item.refresh_from_db()
    assert item.status == Delivery.Status.DELIVERED and item.attempts == 2
    assert len(hook.requests) == 2
    keys = {headers["Idempotency-Key"] for headers, _ in hook.requests}
    assert keys == {str(item.pk)}
    assert b"motor failure" in hook.requests[-1][1]
    deliver.apply(args=[str(item.pk)])  # a duplicate task sends nothing
    assert len(hook.requests) == 2


@pytest.mark.django_db(transaction=True)
def test_a_delivery_gives_up_after_the_last_attempt_with_the_reason(world_tx, webhook, settings):
    settings.ALERT_RETRY_BASE_S = 0
    settings.ALERT_MAX_ATTEMPTS = 3
    settings.ALERT_WEBHOOK_ALLOW_PRIVATE = True  # the receiver is on loopback
    hook = webhook(503, 503, 503, 503)
    _recipients(world_tx.org, hook.url)
    critical_alarm(world_tx.org, world_tx.drone, "x")
    item = Delivery.objects.get()
    deliver.apply(args=[str(item.pk)])
    item.refresh_from_db()
    assert item.status == Delivery.Status.FAILED and item.attempts == 3
    assert "503" in item.last_error and len(hook.requests) == 3


def test_an_email_alert_is_sent_once(world):
    _recipients(world.org, "ops@example.org")
    critical_alarm(world.org, world.drone, "lost GPS")
    item = Delivery.objects.get()
    assert delivery.attempt(str(item.pk)) == "delivered"
    assert delivery.attempt(str(item.pk)) == "done"
    assert len(mail.outbox) == 1
    assert mail.outbox[0].to == ["ops@example.org"]
    assert "lost GPS" in mail.outbox[0].subject


@pytest.mark.django_db(transaction=True)
async def test_open_pages_of_the_organisation_get_the_alert_and_no_one_else(world_tx):
    from asgiref.sync import sync_to_async

    mine, connected, _ = await connect_websocket("/ws/alerts/", world_tx.viewer)
    theirs, other, _ = await connect_websocket("/ws/alerts/", world_tx.outsider)
    assert connected and other
    try:
        assert (await mine.receive_json_from(timeout=5)) == {"type": "recent", "alerts": []}
        await theirs.receive_json_from(timeout=5)

        def raise_one() -> None:
            critical_alarm(world_tx.org, world_tx.drone, "battery critical")

        await sync_to_async(raise_one)()
        message = await mine.receive_json_from(timeout=5)
        assert message["type"] == "alert" and "battery critical" in message["alert"]["title"]
        assert await theirs.receive_nothing(timeout=0.5)
    finally:
        await mine.disconnect()
        await theirs.disconnect()


def test_the_alerts_api_lists_only_the_organisations_alerts(world):
    critical_alarm(world.org, world.drone, "m")
    client = APIClient()
    client.force_authenticate(world.viewer)
    assert len(client.get("/api/v1/alerts/").json()["alerts"]) == 1
    client.force_authenticate(world.outsider)
    assert client.get("/api/v1/alerts/").json()["alerts"] == []


def test_a_critical_alarm_from_a_drone_in_no_mission_still_raises_an_alert(world):
    from missions.alarms import apply_alarm
    from onboard import protocol

    alarm = protocol.Alarm(level="CRITICAL", message="Outside the flight envelope: 130 m high")
    assert apply_alarm(world.drone, alarm) == "alarm_outside_mission"
    alert = Alert.objects.get()
    assert alert.kind == Alert.Kind.CRITICAL_ALARM and "Outside the flight envelope" in alert.title
    assert alert.mission_id is None and alert.drone_id == "ACME_1"
    apply_alarm(world.drone, alarm)  # the same alarm again: no second alert
    assert Alert.objects.count() == 1
    apply_alarm(world.drone, protocol.Alarm(level="OUT_MEASURE", message="CO2"))
    assert Alert.objects.count() == 1
