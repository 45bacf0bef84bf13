"""Faults the replicated ground recovers from on its own:
a gateway killed, a Celery worker killed mid-task, Redis restarted, a broker node killed.
No test helps the platform along: it breaks one part and checks the outcome a user sees."""

from __future__ import annotations

import re
import threading
import time

import pytest

from tests.support.ground import (
    Api,
    PrivateRedis,
    fly_replacement_mission,
    mosquitto_ground,
    rabbitmq_ground,
    wait_for,
)

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]

TWO_OF_EACH = {"web": 2, "gateways": 2, "ingests": 2, "workers": 2}
# Commands wait this long for a reply here (15 s in production): a lost reply shows soon.
FAST_COMMANDS = {"COMMAND_TIMEOUT_S": "8"}


def command_round_trip(api: Api, drone_id: str) -> int:
    """One command through the API to a drone and its reply back; the HTTP status."""
    return api.post(f"/api/v1/drones/{drone_id}/commands/", {"command": "disarm"}).status_code


def answered_commands(api: Api, drone_id: str, count: int) -> list[int]:
    return [command_round_trip(api, drone_id) for _ in range(count)]


@pytest.fixture(params=["mosquitto", "rabbitmq"])
def broker_kind(request):  # type: ignore[no-untyped-def]
    return request.param


def ground_on(kind: str, request, tmp_path, settings, **kwargs):  # type: ignore[no-untyped-def]
    if kind == "mosquitto":
        return mosquitto_ground(tmp_path, settings, **kwargs)
    cluster = request.getfixturevalue("rabbit_cluster")
    return rabbitmq_ground(tmp_path, settings, cluster, **kwargs)


def test_a_gateway_killed_mid_mission_leaves_the_other_to_finish_it_and_answer_commands(
    world_tx, tmp_path, settings, request, broker_kind
):
    """On RabbitMQ the survivor takes over the killed gateway's unacknowledged messages at
    once and the dead one stays dead: it is killed just before the alarm. On Mosquitto a
    killed gateway's persistent session keeps its share of `$share/gateway/...` queued
    until it reconnects (the session outlives it for `persistent_client_expiration`), so
    its supervisor (systemd `Restart=always`, as docs/scaling.md says) starts it again and
    the queued messages then arrive: nothing is lost either way. There an alarm in that
    queue waits for the restart, and a drone may finish its flight first, so the kill
    comes once the alarm is taken, while the replacement takes over."""
    restarts = broker_kind == "mosquitto"
    with ground_on(
        broker_kind, request, tmp_path, settings, env=FAST_COMMANDS, **TWO_OF_EACH
    ) as ground:
        api = Api(world_tx.operator, ground.processes.web_urls)
        idle = f"ACME_{broker_kind[0].upper()}GC"
        # Far away, so the replacement is never this drone (the nearest one is chosen).
        ground.add_drone(idle, world_tx.org.slug, north=500)
        ground.wait_online([idle])
        assert answered_commands(api, idle, 2) == [200, 200]
        replies_after_kill: list[int] = []

        def kill_a_gateway() -> None:
            ground.processes.kill("gateway1")
            # Commands keep coming while the gateway is down (its start-up takes seconds).
            sender = threading.Thread(
                target=lambda: replies_after_kill.extend(answered_commands(api, idle, 4))
            )
            sender.start()
            if restarts:
                ground.processes.restart("gateway1")
            sender.join(60)

        run = fly_replacement_mission(
            ground,
            world_tx.org.slug,
            api,
            world_tx.operator,
            prefix=f"ACME_{broker_kind[0].upper()}G",
            during=kill_a_gateway,
            during_after_alarm=restarts,
        )
        try:
            run.assert_exactly_once()
        finally:
            run.socket.close()
        assert replies_after_kill == [200] * 4
        assert ground.processes["gateway1"].alive == restarts
        assert ground.processes["gateway2"].alive


REPLACEMENT_RECEIVED = r"Task missions\.replace_drone\[([0-9a-f-]+)\] received"
REPLACEMENT_DONE = r"Task missions\.replace_drone\[([0-9a-f-]+)\] succeeded"
# A try that ended: a retry (the alarm's transaction not yet committed) hands the task
# back to the queue, where either worker may take it again under the same id.
REPLACEMENT_ENDED = r"Task missions\.replace_drone\[[0-9a-f-]+\] (?:succeeded|retry|raised)"


def holding_replacement(workers):  # type: ignore[no-untyped-def]
    """The workers that have taken the replacement task and not ended their try."""
    return [
        w
        for w in workers
        if len(re.findall(REPLACEMENT_RECEIVED, w.output()))
        > len(re.findall(REPLACEMENT_ENDED, w.output()))
    ]


def waiting_on_locks() -> int:
    """How many database sessions wait for a lock someone else holds."""
    from django.db import connection

    with connection.cursor() as cursor:
        cursor.execute("SELECT count(*) FROM pg_locks WHERE NOT granted")
        return cursor.fetchone()[0]


def kill_mid_replacement(failing_drone: str, workers, kill) -> str:  # type: ignore[no-untyped-def]
    """Hold the failing drone's assignment row, so the replacement task, once a worker
    takes it, waits inside its transaction (mid-task); `kill(worker)` then; let go.
    Returns the name of the worker that had the task."""
    from django.db import close_old_connections, transaction

    from missions.models import Assignment

    failing = Assignment.objects.get(drone__drone_id=failing_drone)
    holding, release = threading.Event(), threading.Event()

    def hold() -> None:
        try:
            with transaction.atomic():
                Assignment.objects.select_for_update().get(pk=failing.pk)
                holding.set()
                release.wait(60)
        finally:
            close_old_connections()

    holder = threading.Thread(target=hold, daemon=True)
    holder.start()
    assert holding.wait(10)
    try:
        assert wait_for(lambda: holding_replacement(workers), 60), "no worker took the task"
        # Received is not yet running: kill only once the task waits on our lock, in the
        # worker whose try is still open (an earlier try may have been retried).
        assert wait_for(lambda: waiting_on_locks() > 0, 30), "the task never reached the lock"
        taken = wait_for(lambda: holding_replacement(workers), 5) or []
        assert len(taken) == 1, [w.output()[-2000:] for w in workers]
        kill(taken[0])
        return taken[0].name
    finally:
        release.set()
        holder.join(10)


def fly_and_kill(ground, world, kill) -> str:  # type: ignore[no-untyped-def]
    """The replacement mission, its replacement task killed mid-way; the victim's name."""
    api = Api(world.operator, ground.processes.web_urls)
    workers = ground.processes.of_kind("worker")
    victims: list[str] = []
    run = fly_replacement_mission(
        ground,
        world.org.slug,
        api,
        world.operator,
        prefix="ACME_WK",
        during=lambda: victims.append(kill_mid_replacement("ACME_WK1", workers, kill)),
        duplicate_alarm=False,  # so only the killed task's rerun can replace the drone
    )
    try:
        run.assert_exactly_once(duplicate_alarms=0)
    finally:
        run.socket.close()
    return victims[0]


# A slower flight: the killed task runs again while the failing drone still has most of
# its survey ahead.
SLOW_FLIGHT = 4.0


def test_a_celery_worker_killed_mid_task_leaves_the_task_to_the_other_worker_run_once(
    world_tx, tmp_path, settings
):
    # The whole worker dies (-9): its message waits in Redis until the visibility timeout
    # (2 s here; other tasks take milliseconds), then the other worker puts it back.
    short = {"CELERY_VISIBILITY_TIMEOUT": "2"}
    with mosquitto_ground(
        tmp_path, settings, env=short, time_scale=SLOW_FLIGHT, web=1, gateways=1, workers=2
    ) as ground:
        victim = fly_and_kill(ground, world_tx, lambda worker: worker.kill())
        (survivor,) = [w for w in ground.processes.of_kind("worker") if w.name != victim]
        victim_ids = re.findall(REPLACEMENT_RECEIVED, ground.processes[victim].output())
        assert victim_ids and victim_ids[0] in re.findall(REPLACEMENT_DONE, survivor.output()), (
            ground.processes.describe()
        )
        assert not ground.processes[victim].alive


def test_a_pool_process_killed_mid_task_has_its_task_put_back_at_once_and_run_once(
    world_tx, tmp_path, settings
):
    import psutil

    # Prefork workers: the process running the task dies (-9, as the OOM killer does) while
    # its worker lives; task_reject_on_worker_lost puts the message straight back.
    with mosquitto_ground(
        tmp_path, settings, time_scale=SLOW_FLIGHT, web=1, gateways=1, workers=0
    ) as ground:
        for _ in range(2):
            ground.processes.add_worker(pool="prefork", concurrency=1)
        ground.processes.start()

        def kill_pool_process(worker) -> None:  # type: ignore[no-untyped-def]
            for child in psutil.Process(worker.process.pid).children(recursive=True):
                child.kill()

        victim = fly_and_kill(ground, world_tx, kill_pool_process)
        victim_ids = re.findall(REPLACEMENT_RECEIVED, ground.processes[victim].output())
        everything = "".join(w.output() for w in ground.processes.of_kind("worker"))
        assert victim_ids and victim_ids[0] in re.findall(REPLACEMENT_DONE, everything)
        assert wait_for(lambda: "WorkerLostError" in ground.processes[victim].output(), 10)
        assert all(w.alive for w in ground.processes.of_kind("worker"))


def test_a_redis_restart_is_survived_by_the_outbox_counters_channel_layer_and_celery(
    world_tx, tmp_path, settings
):
    import redis
    from websockets.sync.client import connect

    from tests.support.websocket import session_cookie

    private = PrivateRedis(tmp_path / "redis").start()
    try:
        with mosquitto_ground(
            tmp_path,
            settings,
            redis_url=private.url,
            env=FAST_COMMANDS,
            web=1,
            gateways=1,
            ingests=1,
            workers=1,
        ) as ground:
            api = Api(world_tx.operator, ground.processes.web_urls)
            ground.add_drone("ACME_RD1", world_tx.org.slug)
            ground.wait_online(["ACME_RD1"])
            assert command_round_trip(api, "ACME_RD1") == 200

            private.stop()
            time.sleep(1.0)  # every process notices: connections refused, not just idle
            private.start()

            # The gateway's outbox (and the web's reply wait): a command gets its reply.
            assert wait_for(lambda: command_round_trip(api, "ACME_RD1") == 200, 30)
            client = redis.Redis.from_url(private.url)
            # Counters flushed again into the empty Redis.
            assert wait_for(lambda: list(client.scan_iter("skyhive:counters:gateway*")), 10)
            # Celery: the worker takes beat's tasks from the new Redis.
            worker = ground.processes["worker1"]
            done_before = worker.output().count("succeeded in")
            assert wait_for(lambda: worker.output().count("succeeded in") > done_before, 20), (
                ground.processes.describe()
            )
            # Channel layer: the fleet page gets live updates pushed by the gateway.
            web = ground.processes.web_urls[0]
            headers = {"Cookie": session_cookie(world_tx.operator).decode(), "Origin": web}
            url = web.replace("http://", "ws://") + f"/ws/fleet/?org={world_tx.org.slug}"
            with connect(url, additional_headers=headers, open_timeout=10) as ws:
                import json

                assert json.loads(ws.recv(timeout=10))["type"] == "snapshot"
                update = json.loads(ws.recv(timeout=10))
                assert "ACME_RD1" in json.dumps(update)
            assert all(p.alive for p in ground.processes.processes.values())
    finally:
        private.stop()


def test_a_broker_node_killed_mid_mission_moves_drones_and_ground_to_the_other_node(
    world_tx, tmp_path, settings, rabbit_cluster
):
    # Node 2 is the one killed. Node 1 formed the cluster and leads the MQTT plugin's
    # client-id Raft group; a group of two that loses its leader has no majority, and the
    # leader started again serves MQTT only after the plugin's 100 s start timeout
    # (RabbitMQ 3.10's mqtt_node), where a follower is back in about 5 s.
    # A slower flight: on a loaded machine the drone's messages of the first seconds after
    # the kill (its alarm among them) have reached the ground over 4 s late, once the drone
    # had flown its whole survey; the ground then rightly had nothing left to hand over.
    try:
        with rabbitmq_ground(
            tmp_path,
            settings,
            rabbit_cluster,
            env=FAST_COMMANDS,
            first_node=2,
            time_scale=SLOW_FLIGHT,
            **TWO_OF_EACH,
        ) as ground:
            api = Api(world_tx.operator, ground.processes.web_urls)
            # Drones try node 2 first, as do the gateways and ingests: killing node 2 moves
            # every connection to node 1, whose mirrors of the queues take over.
            run = fly_replacement_mission(
                ground,
                world_tx.org.slug,
                api,
                world_tx.operator,
                prefix="ACME_NK",
                during=lambda: rabbit_cluster.kill_node(2),
            )
            try:
                run.assert_exactly_once()
            finally:
                run.socket.close()
            assert all(p.alive for p in ground.processes.processes.values())
            assert all("next node" in p.output() for p in ground.processes.of_kind("gateway"))
    finally:
        # The cluster is the session's: whole again for the tests after this one.
        rabbit_cluster.start_node(2)
