"""The operations figures: process instances alive and gone, the broker's own figures from
a real Mosquitto and a real RabbitMQ cluster as the gateways write them, sources that
cannot be read, who may look, and the page in a browser."""

from __future__ import annotations

import contextlib
import subprocess
import time
import urllib.parse
import urllib.request
import uuid

import pytest
from django.test import Client, override_settings
from rest_framework.test import APIClient

from runtime import processes
from runtime.processes import free_port, stop_process
from tests.conftest import login
from tests.support.celery_worker import start_worker, worker_env
from workers import operations, outbox
from workers.broker import figures as broker_figures
from workers.broker import mosquitto_sys
from workers.broker.credentials import render_acl
from workers.counters import Counters, instances, start_heartbeat
from workers.gateway import Gateway
from workers.mosquitto import start_broker


def wait_for(condition, timeout: float = 10.0, every: float = 0.1):  # type: ignore[no-untyped-def]
    """The shared wait_for, failing the test when the condition is never met."""
    value = processes.wait_for(condition, timeout, every)
    if not value:
        raise AssertionError("condition not met in time")
    return value


def api_as(user) -> APIClient:  # type: ignore[no-untyped-def]
    client = APIClient()
    client.force_authenticate(user)
    return client


def by_instance(figures: dict, process: str) -> dict[str, dict]:
    group = figures["instances"]["processes"].get(process, {"instances": []})
    return {i["instance"]: i for i in group["instances"]}


@pytest.fixture
def sys_broker(tmp_path):
    """Mosquitto with the ACL that fleet.credentials writes for the ground and ACME_1."""
    with override_settings(MQTT_URL="mqtt://ground:g@127.0.0.1:1883", MQTT_SERVICE_USERS=[]):
        acl = render_acl(["ACME_1"])
    broker = start_broker(tmp_path / "sys", {"ground": "g", "ACME_1": "a"}, acl=acl)
    yield broker
    broker.stop()


@contextlib.contextmanager
def gateway_on(url: str):  # type: ignore[no-untyped-def]
    """A running gateway on Mosquitto at `url`: what writes the broker's figures."""
    gateway = Gateway(
        url,
        counters=Counters("gateway", instance=f"ops-gw-{uuid.uuid4().hex[:8]}", flush_every=1e9),
    )
    gateway.start()
    try:
        yield gateway
    finally:
        gateway.stop()


def broker_now(url: str) -> dict:
    with override_settings(MQTT_URL=url, MQTT_BROKER="mosquitto"):
        return operations.broker_figures_now()


# -- instances --------------------------------------------------------------------------------


def test_two_running_gateways_are_listed_and_a_stopped_one_turns_gone_after_its_ttl(
    world_tx, sys_broker
):
    world = world_tx
    tag = uuid.uuid4().hex[:8]
    gateways = [
        Gateway(
            sys_broker.url_for("ground"),
            counters=Counters("gateway", instance=f"ops-{tag}-{n}", instance_ttl=1.5),
        )
        for n in (1, 2)
    ]
    for gateway in gateways:
        gateway.start()
    try:
        for gateway in gateways:
            assert gateway.wait_connected(10)
        api = api_as(world.operator)

        def mine() -> dict[str, dict]:
            figures = api.get("/api/v1/operations/").json()
            return {k: v for k, v in by_instance(figures, "gateway").items() if tag in k}

        with override_settings(MQTT_URL=sys_broker.url_for("ground")):
            listed = wait_for(lambda: (found := mine()) and len(found) == 2 and found)
        assert all(i["alive"] for i in listed.values())
        assert {i["pid"] for i in listed.values()} and all(i["host"] for i in listed.values())

        gateways[0].stop()
        stopped, running = f"ops-{tag}-1", f"ops-{tag}-2"
        gone = wait_for(
            lambda: (found := mine()) and not found[stopped]["alive"] and found, timeout=6
        )
        assert gone[running]["alive"], "the gateway still running stays alive"
        assert time.time() - gone[stopped]["last_report"] >= 1.5
        watch = {w["key"]: w for w in api.get("/api/v1/operations/").json()["watch"]}
        assert watch["gateway_instances"]["state"] == "warn", "one went lately"
        assert watch["gateway_instances"]["value"] >= 1
    finally:
        for gateway in gateways:
            if not gateway.stopping.is_set():
                gateway.stop()


def test_an_instance_reports_while_idle_and_keeps_its_own_counters(db):
    counters = Counters("ingest", instance=f"ops-idle-{uuid.uuid4().hex[:8]}", instance_ttl=2)
    counters.incr("stored", 7)
    counters.flush()
    counters.flush()  # nothing counted: still a heartbeat
    mine = next(i for i in instances() if i.instance == counters.instance)
    assert mine.alive and mine.process == "ingest"
    assert mine.counters["stored"] == 7, "the instance's own count, not the totals"


def test_a_process_with_nothing_to_count_reports_through_a_heartbeat_and_retires_at_once(db):
    instance = f"ops-web-{uuid.uuid4().hex[:8]}"
    heartbeat = start_heartbeat("web", instance=instance, instance_ttl=1.0, flush_every=0.2)
    try:
        time.sleep(1.5)  # longer than the TTL: only the thread's renewals keep it alive
        assert next(i for i in instances() if i.instance == instance).alive
    finally:
        heartbeat.stop()
    assert not next(i for i in instances() if i.instance == instance).alive


def test_a_web_server_is_listed_with_the_requests_it_served_and_retires_when_stopped(
    transactional_db,
):
    from django.db import connection

    from tests.support.live import LiveServer

    server = LiveServer(connection.settings_dict["NAME"])
    try:
        for _ in range(3):
            urllib.request.urlopen(f"{server.url}/accounts/login/", timeout=10).read()

        def mine() -> object:
            found = [i for i in instances() if i.process == "web" and i.pid == server.process.pid]
            return found[0] if found else None

        web = wait_for(lambda: (i := mine()) and i.counters.get("requests", 0) >= 3 and i)
        assert web and web.alive, instances()
    finally:
        server.stop()
    # uvicorn shuts the app down (lifespan), then re-raises SIGTERM for its exit status.
    assert not mine().alive, "a clean stop retires the instance at once"


def test_ingest_lag_above_a_second_is_highlighted_as_bad(db):
    counters = Counters("ingest", instance=f"ops-lag-{uuid.uuid4().hex[:8]}", instance_ttl=5)
    counters.gauge("lag_s", 2.5)
    counters.gauge("alive_at", time.time())
    counters.flush()
    try:
        watch = {w["key"]: w for w in operations.gather()["watch"]}
        assert watch["ingest_lag"]["value"] >= 2.5
        assert watch["ingest_lag"]["state"] == "bad"
        assert watch["ingest_lag"]["at"] > time.time() - 10
    finally:
        counters.retire()


def test_rising_gateway_drops_are_flagged(db, monkeypatch):
    monkeypatch.setattr(operations, "TREND_MIN_AGE_S", 0.0)
    counters = Counters("gateway", instance=f"ops-drop-{uuid.uuid4().hex[:8]}", instance_ttl=2)
    operations.gather()
    counters.incr("dropped", 3)
    counters.incr("dropped.malformed", 3)
    counters.flush()
    figures = operations.gather()
    watch = {w["key"]: w for w in figures["watch"]}
    assert watch["gateway_dropped"]["state"] == "warn"
    assert figures["gateway"]["dropped"]["malformed"] >= 3


def test_a_running_celery_worker_is_listed_alive_and_gone_once_stopped(transactional_db):
    from django.db import connection

    name = f"ops-{uuid.uuid4().hex[:6]}@test"
    env = worker_env(connection.settings_dict["NAME"])
    worker = start_worker(name, env, output=subprocess.DEVNULL, queue=f"ops-{name}")
    try:

        def listed() -> dict | None:
            celery = operations.gather()["instances"]["processes"]["celery"]
            return next((w for w in celery["instances"] if w["instance"] == name), None)

        worker_row = wait_for(lambda: (w := listed()) and w["alive"] and w, timeout=60, every=0.5)
        assert worker_row["host"] == "test"
        worker.terminate()
        worker.wait(15)
        assert wait_for(lambda: (w := listed()) and not w["alive"], timeout=10)
    finally:
        stop_process(worker)


# -- the broker: Mosquitto --------------------------------------------------------------------


def test_mosquitto_figures_come_from_its_sys_topics(world, sys_broker):
    import paho.mqtt.client as mqtt

    drone = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id="ACME_1")
    drone.username_pw_set("ACME_1", "a")
    drone.connect("127.0.0.1", sys_broker.port)
    drone.loop_start()
    url = sys_broker.url_for("ground")
    try:
        with gateway_on(url), override_settings(MQTT_URL=url, MQTT_BROKER="mosquitto"):
            # The retained figures come at once; the periodic ones (the store's count) with
            # the next $SYS round, every 10 s.
            wait_for(lambda: "store_messages" in broker_now(url), timeout=25)
            figures = api_as(world.owner).get("/api/v1/operations/").json()
        broker = figures["broker"]
        assert broker["available"] and broker["kind"] == "mosquitto"
        assert broker["version"].startswith("mosquitto")
        assert isinstance(broker["clients_connected"], int)
        assert isinstance(broker["store_messages"], int)
        assert broker["nodes_down"] == 0 and broker["at"] > time.time() - 10
        watch = {w["key"]: w for w in figures["watch"]}
        assert watch["broker_nodes_down"]["state"] == "ok"
        assert watch["broker_depth"]["state"] in ("ok", "warn")
    finally:
        drone.loop_stop()
        drone.disconnect()


@pytest.fixture
def fast_sys_broker(tmp_path):
    """The same, publishing $SYS every second instead of every ten."""
    with override_settings(MQTT_URL="mqtt://ground:g@127.0.0.1:1883", MQTT_SERVICE_USERS=[]):
        acl = render_acl(["ACME_1"])
    broker = start_broker(
        tmp_path / "fastsys",
        {"ground": "g", "ACME_1": "a"},
        acl=acl,
        extra_config="sys_interval 1\n",
    )
    yield broker
    broker.stop()


def test_a_gateway_keeps_watching_mosquittos_client_count(db, fast_sys_broker, settings):
    """Mosquitto's counts expire from $SYS a minute after they last change: the gateways
    follow every change so the page still has them."""
    import paho.mqtt.client as mqtt

    from workers import outbox

    settings.MQTT_BROKER = "mosquitto"
    gateway = Gateway(
        fast_sys_broker.url_for("ground"),
        counters=Counters("gateway", instance=f"ops-sys-{uuid.uuid4().hex[:8]}", flush_every=1e9),
    )
    gateway.start()
    view = lambda: mosquitto_sys.remembered(outbox.sync_redis()).get("clients_connected")  # noqa: E731
    drone = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id="ACME_1")
    try:
        assert gateway.wait_connected(10)
        before = wait_for(view, timeout=5)
        assert before and before >= 1
        drone.username_pw_set("ACME_1", "a")
        drone.connect("127.0.0.1", fast_sys_broker.port)
        drone.loop_start()
        assert wait_for(lambda: view() == before + 1, timeout=5), view()
        drone.disconnect()
        drone.loop_stop()
        assert wait_for(lambda: view() == before, timeout=5), view()
    finally:
        gateway.stop()
    assert not outbox.sync_redis().exists(gateway.sys_view.key), "a stopped gateway's view goes"


def test_the_most_recently_written_gateway_view_wins():
    older = {"at": "100.0", "clients_connected": "12", "version": "mosquitto version 2.0.11"}
    newer = {"at": "200.0", "clients_connected": "13", "_link": "up", "subscriptions": "30"}
    assert mosquitto_sys.merged([older, newer]) == {
        "clients_connected": 13,
        "version": "mosquitto version 2.0.11",
        "subscriptions": 30,
    }


def test_the_page_shows_the_gateways_client_count(world_tx, fast_sys_broker, settings):
    settings.MQTT_BROKER = "mosquitto"
    settings.MQTT_URL = fast_sys_broker.url_for("ground")
    gateway = Gateway(
        fast_sys_broker.url_for("ground"),
        counters=Counters("gateway", instance=f"ops-sys-{uuid.uuid4().hex[:8]}", flush_every=1e9),
    )
    gateway.start()
    try:
        assert gateway.wait_connected(10)
        api = api_as(world_tx.operator)
        broker = wait_for(
            lambda: (
                (b := api.get("/api/v1/operations/").json()["broker"])
                and b.get("clients_connected")
                and b
            ),
            timeout=5,
        )
        assert broker["available"] and broker["clients_connected"] >= 1
    finally:
        gateway.stop()


def test_a_broker_that_hides_sys_is_shown_unreadable_not_zero(tmp_path):
    # `#` alone does not reach $SYS: what an ACL written by hand often says.
    broker = start_broker(
        tmp_path / "nosys", {"ground": "g"}, acl="user ground\ntopic readwrite #\n"
    )
    url = broker.url_for("ground")
    try:
        with gateway_on(url) as gateway:
            assert gateway.wait_connected(10)
            figures = wait_for(lambda: (b := broker_now(url)) and b.get("nodes_up") and b, 5)
    finally:
        broker.stop()
    assert figures["available"] is False and "$SYS" in figures["error"]
    assert "clients_connected" not in figures


def test_a_stopped_mosquitto_is_a_node_down(db):
    url = f"mqtt://ground:g@127.0.0.1:{free_port()}"
    with gateway_on(url):
        figures = wait_for(lambda: (b := broker_now(url)) and "nodes_down" in b and b, 5)
        assert figures["available"] is False and figures["nodes_down"] == 1
        with override_settings(MQTT_URL=url, MQTT_BROKER="mosquitto"):
            watch = {w["key"]: w for w in operations.gather()["watch"]}
    assert watch["broker_nodes_down"]["state"] == "bad"
    assert watch["broker_depth"]["state"] == "unknown" and watch["broker_depth"]["value"] is None


# -- the broker: RabbitMQ cluster -------------------------------------------------------------


def test_rabbitmq_figures_show_both_nodes_and_the_depth_of_a_filled_queue(world, rabbit_cluster):
    name = f"skyhive.ops-test-{uuid.uuid4().hex[:6]}"
    vhost_queue = f"%2F/{urllib.parse.quote(name, safe='')}"
    rabbit_cluster.api("PUT", f"queues/{vhost_queue}", {"durable": False, "auto_delete": False})
    try:
        for n in range(5):
            rabbit_cluster.api(
                "POST",
                "exchanges/%2F/amq.default/publish",
                {
                    "properties": {},
                    "routing_key": name,
                    "payload": f"m{n}",
                    "payload_encoding": "string",
                },
            )
        api_urls = rabbit_cluster.settings_env()["RABBITMQ_API_URLS"].split(",")
        # What every gateway on RabbitMQ runs.
        poller = broker_figures.RabbitMQPoller(outbox.sync_redis(), api_urls)
        poller.start()
        with override_settings(MQTT_BROKER="rabbitmq", RABBITMQ_API_URLS=api_urls):

            def filled() -> dict | None:
                figures = api_as(world.owner).get("/api/v1/operations/").json()
                queues = figures["broker"].get("queues", [])
                return (
                    figures if any(q["name"] == name and q["ready"] == 5 for q in queues) else None
                )

            # The management API refreshes queue figures every few seconds.
            figures = wait_for(filled, timeout=15, every=1.0)
        poller.stop()
        broker = figures["broker"]
        assert broker["kind"] == "rabbitmq" and broker["available"]
        assert broker["nodes_up"] == 2 and broker["nodes_down"] == 0
        assert all(e["up"] for e in broker["endpoints"])
        assert broker["connections"] is not None and "queues" in broker["mqtt_sessions"]
        watch = {w["key"]: w for w in figures["watch"]}
        assert watch["broker_depth"]["value"] >= 5
        assert watch["broker_nodes_down"]["state"] == "ok"
    finally:
        rabbit_cluster.api("DELETE", f"queues/{vhost_queue}")


def test_an_unreachable_rabbitmq_node_is_reported_down(rabbit_cluster):
    # Node 1 of the real cluster answers; the second address has no node behind it (killing
    # and restarting a real node costs a minute here; the fault tests do that).
    missing = f"127.0.0.1:{free_port()}"
    urls = [rabbit_cluster.api_urls[0], f"http://u:p@{missing}/api"]
    figures = broker_figures.rabbitmq_figures(urls)
    assert figures["available"], "node 1 still answers for the cluster"
    assert [e["address"] for e in figures["endpoints"] if not e["up"]] == [missing]
    assert figures["nodes_down"] == 1
    watch = {
        w["key"]: w
        for w in operations.watch(
            {
                "generated_at": time.time(),
                "ingest": {"available": False},
                "gateway": {"available": False},
                "queues": {"available": False},
                "instances": {"available": False},
                "broker": figures,
            }
        )
    }
    assert watch["broker_nodes_down"]["state"] == "bad"
    assert missing in watch["broker_nodes_down"]["detail"]
    assert watch["ingest_lag"]["state"] == "unknown", "an unread source is unknown, not ok"


def test_a_node_that_refuses_our_credentials_is_up_but_unreadable(rabbit_cluster):
    parts = urllib.parse.urlsplit(rabbit_cluster.api_urls[0])
    figures = broker_figures.rabbitmq_figures(
        [f"http://nobody:wrong@{parts.hostname}:{parts.port}/api"]
    )
    assert figures["available"] is False and "401" in figures["error"]
    assert figures["nodes_down"] == 0


def test_no_answering_rabbitmq_node_means_unreachable_not_zero():
    urls = [f"http://u:p@127.0.0.1:{free_port()}/api", f"http://u:p@127.0.0.1:{free_port()}/api"]
    figures = broker_figures.rabbitmq_figures(urls)
    assert figures["available"] is False
    assert figures["nodes_down"] == 2 and "queues" not in figures


# -- who may look -----------------------------------------------------------------------------


def test_operators_and_admins_see_the_operations_page_and_viewers_do_not(world):
    for person, code in ((world.owner, 200), (world.operator, 200), (world.viewer, 403)):
        assert api_as(person).get("/api/v1/operations/").status_code == code
        client = Client()
        client.force_login(person)
        page = client.get("/operations/")
        assert page.status_code == code
        nav = client.get("/telemetry/status/").content.decode()
        assert ('href="/operations/"' in nav) is (code == 200)
    assert APIClient().get("/api/v1/operations/").status_code in (401, 403)
    assert Client().get("/operations/").status_code == 302


# -- the page in a browser --------------------------------------------------------------------


@pytest.mark.browser
def test_the_operations_page_shows_instances_and_refreshes_itself(page, live_asgi, world_tx):
    counters = Counters("gateway", instance=f"ops-page-{uuid.uuid4().hex[:8]}", instance_ttl=30)
    counters.incr("dropped.malformed", 1)
    counters.flush()
    try:
        login(page, live_asgi, "operator")
        page.click("nav >> text=Operations")
        page.wait_for_url(f"{live_asgi.url}/operations/")
        row = page.locator(f"tr[data-instance='{counters.instance}']")
        row.wait_for()
        assert "alive" in row.inner_text()
        assert page.locator("#ops-watch .ops-item[data-key=ingest_lag]").count() == 1
        assert page.locator("#ops-watch .ops-item").count() >= 8
        assert page.locator("#ops-gateway-dropped").inner_text().count("malformed") == 1
        first = page.get_attribute("#ops-updated", "data-generated-at")
        page.wait_for_function(
            "(first) => document.getElementById('ops-updated').dataset.generatedAt !== first",
            arg=first,
            timeout=15_000,
        )
        counters.retire()
        page.wait_for_function(
            f"() => document.querySelector(\"tr[data-instance='{counters.instance}'] .badge\")"
            ".textContent === 'gone'",
            timeout=15_000,
        )
        page.goto(f"{live_asgi.url}/telemetry/status/")
        page.locator("#ops-watch .ops-item[data-key=broker_nodes_down]").wait_for()
    finally:
        counters.retire()


# -- Redis away -------------------------------------------------------------------------------


def test_with_redis_away_counts_are_kept_and_its_figures_show_unreachable(db):
    counters = Counters("gateway", instance=f"ops-redis-{uuid.uuid4().hex[:8]}", instance_ttl=5)
    away = f"redis://127.0.0.1:{free_port()}/0"
    with override_settings(REDIS_URL=away):
        counters.incr("received", 4)
        counters.flush()  # refused: the counts stay in memory
        figures = operations.gather()
    for source in ("instances", "gateway", "ingest", "queues"):
        assert figures[source]["available"] is False, source
        assert figures[source]["error"] and figures[source]["at"]
    watch = {w["key"]: w for w in figures["watch"]}
    assert watch["ingest_lag"]["state"] == "unknown" and watch["outbox"]["value"] is None
    assert watch["gateway_instances"]["state"] == "unknown"

    counters.flush()  # Redis is back
    mine = next(i for i in instances() if i.instance == counters.instance)
    assert mine.alive and mine.counters["received"] == 4
    counters.retire()
