"""Every ground process twice: a mission with replacement flown by
simulated drones through two web instances, two gateways, two ingests and two Celery
workers decides once, tracks every step once and stores every telemetry sample once."""

from __future__ import annotations

import uuid

import pytest

from tests.support.ground import (
    Api,
    Telemetry,
    fly_replacement_mission,
    mosquitto_ground,
    rabbitmq_ground,
)

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]

TWO_OF_EACH = {"web": 2, "gateways": 2, "ingests": 2, "workers": 2}


def fly_and_check(ground, world) -> None:  # type: ignore[no-untyped-def]
    api = Api(world.operator, ground.processes.web_urls)
    # A new drone id each time: a durable RabbitMQ queue may still hold an earlier run's.
    telemetry = Telemetry.start(ground, world.org.slug, f"ACME_T{uuid.uuid4().hex[:8]}")
    run = fly_replacement_mission(ground, world.org.slug, api, world.operator)
    try:
        telemetry.assert_stored_once()
        run.assert_exactly_once()
    finally:
        run.socket.close()
    # Both web instances answered the API; both workers took tasks; nothing crashed.
    assert all(calls > 0 for calls in api.calls)
    assert all(p.alive for p in ground.processes.processes.values()), ground.processes.describe()
    for worker in ground.processes.of_kind("worker"):
        assert "succeeded in" in worker.output(), ground.processes.describe()


def test_two_of_every_process_on_mosquitto_decide_a_replacement_once_and_lose_nothing(
    world_tx, tmp_path, settings
):
    with mosquitto_ground(tmp_path, settings, **TWO_OF_EACH) as ground:
        fly_and_check(ground, world_tx)


def test_two_of_every_process_on_a_rabbitmq_cluster_decide_a_replacement_once_and_lose_nothing(
    world_tx, tmp_path, settings, rabbit_cluster
):
    with rabbitmq_ground(tmp_path, settings, rabbit_cluster, **TWO_OF_EACH) as ground:
        fly_and_check(ground, world_tx)
