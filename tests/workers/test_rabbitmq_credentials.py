"""Per-drone users and topic permissions on a real two-node RabbitMQ cluster.

Each drone may publish only `<id>/<channel>/out` and subscribe only `<id>/<channel>/in`,
through either node; anything else gets its connection closed and the message dropped.
Revocation closes a live connection at once. The Mosquitto backend's bulk path is
checked on a private Mosquitto at the end.
"""

from __future__ import annotations

import io
import json
import re
import threading
import time
import uuid
from urllib.parse import urlsplit

import paho.mqtt.client as mqtt
import pytest
from django.core.management import call_command
from django.test import Client

from fleet import credentials
from fleet.models import Drone
from runtime.processes import wait_for
from workers.broker.rabbitmq_admin import RabbitMQAdmin, RabbitMQAdminError, rabbit_password_hash
from workers.mosquitto import start_broker

pytestmark = pytest.mark.django_db(transaction=True)


# -- fixtures and helpers -----------------------------------------------------------------


@pytest.fixture
def rabbit(rabbit_cluster, settings):  # type: ignore[no-untyped-def]
    """The settings of a ground process on the cluster; no drone user before or after."""
    env = rabbit_cluster.settings_env()
    settings.MQTT_BROKER = "rabbitmq"
    settings.MQTT_URL = env["MQTT_URL"]
    settings.MQTT_URLS = env["MQTT_URLS"].split(",")
    settings.AMQP_URLS = env["AMQP_URLS"].split(",")
    settings.RABBITMQ_API_URLS = env["RABBITMQ_API_URLS"].split(",")
    settings.MQTT_PUBLIC_HOST = ""
    settings.MQTT_PUBLIC_PORT = 0
    admin = RabbitMQAdmin(settings.RABBITMQ_API_URLS)
    _forget_drone_users(admin)
    yield rabbit_cluster
    _forget_drone_users(admin)


# The drones these tests create: only they are cleaned up, as other scale tests of the
# session share the cluster.
OURS = r"(ACME_1|GLOBEX_1|NEW_9|FRESH_1|STALE_1|BATCH_\d+)"


def _forget_drone_users(admin: RabbitMQAdmin) -> None:
    ours = [
        u["name"]
        for u in admin.users()
        if credentials.DRONE_TAG in u["tags"] and re.fullmatch(OURS, u["name"])
    ]
    admin.delete_users(ours)
    for queue in admin.queues_named(f"^mqtt-subscription-(skyhive-agent-)?{OURS}qos[01]$"):
        admin.delete_queue(queue)


class Peer:
    """A connected paho client that records what it receives and whether it was cut off."""

    def __init__(
        self, url: str, client_id: str, *, clean_session: bool = True, connect_timeout: float = 5
    ) -> None:
        parts = urlsplit(url)
        self.received: list[tuple[str, bytes]] = []
        self.disconnected = threading.Event()
        self.client = mqtt.Client(
            mqtt.CallbackAPIVersion.VERSION2, client_id=client_id, clean_session=clean_session
        )
        self.client.username_pw_set(parts.username, parts.password)
        self.client.reconnect_delay_set(60, 60)  # no silent reconnection during a test
        self.client.on_message = lambda c, u, m: self.received.append((m.topic, m.payload))
        self.client.on_disconnect = lambda *args: self.disconnected.set()
        connected = threading.Event()
        outcome: dict = {}

        def on_connect(c, userdata, flags, reason_code, properties):  # type: ignore[no-untyped-def]
            outcome["rc"] = reason_code
            connected.set()

        self.client.on_connect = on_connect
        self.client.connect(parts.hostname, parts.port, keepalive=10)
        self.client.loop_start()
        connected.wait(connect_timeout)
        if "rc" not in outcome or outcome["rc"].is_failure:
            self.stop()
            raise ConnectionRefusedError(str(outcome.get("rc")))

    def subscribe(self, topic: str, qos: int = 1) -> None:
        """Return once the broker answered: SUBACK, or the cut-off a forbidden filter gets."""
        answered = threading.Event()
        self.client.on_subscribe = lambda *args: answered.set()
        self.client.subscribe(topic, qos=qos)
        deadline = time.monotonic() + 10
        while not (answered.is_set() or self.disconnected.is_set()):
            if time.monotonic() > deadline:
                raise TimeoutError(f"no answer to subscribing to {topic}")
            time.sleep(0.02)
        time.sleep(0.3)  # a refusal in the SUBACK is followed by the connection's close

    def publish(self, topic: str, payload: bytes, qos: int = 1) -> None:
        """Return once the broker took the message (PUBACK for QoS 1), or the link closed."""
        info = self.client.publish(topic, payload, qos=qos)
        deadline = time.monotonic() + 10
        while qos and not (info.is_published() or self.disconnected.is_set()):
            if time.monotonic() > deadline:
                raise TimeoutError(f"no PUBACK for {topic}")
            time.sleep(0.02)

    def topics(self) -> list[str]:
        return [topic for topic, _ in self.received]

    def stop(self) -> None:
        self.client.disconnect()
        self.client.loop_stop()


def drone_url(issued: credentials.Credentials, node: int) -> str:
    return issued.urls[node - 1]


def ground_peer(cluster, node: int) -> Peer:  # type: ignore[no-untyped-def]
    return Peer(cluster.mqtt_urls[node - 1], f"ground-test-{uuid.uuid4().hex[:8]}")


# -- provisioning and isolation -----------------------------------------------------------


def test_a_provisioned_drone_publishes_its_out_and_receives_its_in_through_either_node(
    world_tx, rabbit
):
    issued = credentials.provision("ACME_1")
    assert [urlsplit(u).port for u in issued.urls] == [rabbit.mqtt_port(1), rabbit.mqtt_port(2)]
    stored = Drone.objects.get(drone_id="ACME_1").mqtt_password_hash
    assert stored.startswith("$7$") and issued.password not in stored
    assert credentials.check_password(issued.password, stored)

    for node, client_id in ((1, "ACME_1"), (2, "skyhive-agent-ACME_1")):
        _exchange_through(rabbit, drone_url(issued, node), client_id, ground_node=3 - node)


def _exchange_through(cluster, url: str, client_id: str, ground_node: int) -> None:  # type: ignore[no-untyped-def]
    """The drone's heartbeat reaches the ground, and a command reaches the drone."""
    ground = ground_peer(cluster, ground_node)
    ground.subscribe("ACME_1/+/out")
    drone = Peer(url, client_id)
    drone.subscribe("ACME_1/+/in")
    drone.publish("ACME_1/heartbeats/out", b"beat")
    ground.publish("ACME_1/control/in", b"arm")
    assert wait_for(lambda: ("ACME_1/heartbeats/out", b"beat") in ground.received)
    assert wait_for(lambda: ("ACME_1/control/in", b"arm") in drone.received)
    assert not drone.disconnected.is_set()
    drone.stop()
    ground.stop()


def test_the_provisioning_json_lists_every_node_for_failover(world_tx, rabbit):
    out = io.StringIO()
    call_command("provision_drone", "NEW_9", "--org", "acme", stdout=out)
    printed = json.loads(out.getvalue())
    mqtt_part = printed["mqtt"]
    assert mqtt_part["username"] == "NEW_9"
    assert (mqtt_part["host"], mqtt_part["port"]) == ("127.0.0.1", rabbit.mqtt_port(1))
    password = mqtt_part["password"]
    assert mqtt_part["urls"] == [
        f"mqtt://NEW_9:{password}@127.0.0.1:{rabbit.mqtt_port(i)}" for i in (1, 2)
    ]
    Peer(mqtt_part["urls"][1], "NEW_9").stop()


def test_a_drone_publishing_on_another_drones_topics_is_cut_off_and_nothing_reaches_anyone(
    world_tx, rabbit
):
    spy_creds = credentials.provision("ACME_1")
    victim_creds = credentials.provision("GLOBEX_1")
    ground = ground_peer(rabbit, 1)
    ground.subscribe("#")
    victim = Peer(drone_url(victim_creds, 1), "GLOBEX_1")
    victim.subscribe("GLOBEX_1/+/in")

    for forbidden in ("GLOBEX_1/heartbeats/out", "GLOBEX_1/control/in", "ACME_1/control/in"):
        spy = Peer(drone_url(spy_creds, 2), "ACME_1")
        spy.publish("ACME_1/heartbeats/out", b"allowed")
        spy.publish(forbidden, b"forged")
        assert spy.disconnected.wait(5), f"publishing on {forbidden} was tolerated"
        spy.stop()
    # A message the ground sends afterwards arrives: the forged ones had their chance.
    ground.publish("GLOBEX_1/control/in", b"from-ground")
    assert wait_for(lambda: ("GLOBEX_1/control/in", b"from-ground") in victim.received)
    assert wait_for(lambda: ground.topics().count("ACME_1/heartbeats/out") == 3)
    assert b"forged" not in [payload for _, payload in ground.received + victim.received]
    assert not victim.disconnected.is_set()
    victim.stop()
    ground.stop()


@pytest.mark.parametrize(
    "topic_filter", ["GLOBEX_1/control/in", "+/control/in", "#", "ACME_1/#", "GLOBEX_1/+/out"]
)
def test_a_drone_subscribing_beyond_its_own_commands_is_cut_off_and_reads_nothing(
    world_tx, rabbit, topic_filter
):
    spy_creds = credentials.provision("ACME_1")
    credentials.provision("GLOBEX_1")
    spy = Peer(drone_url(spy_creds, 1), "ACME_1")
    spy.subscribe(topic_filter)
    assert spy.disconnected.wait(5), f"subscribing to {topic_filter} was tolerated"
    ground = ground_peer(rabbit, 2)
    ground.publish("GLOBEX_1/control/in", b"secret")
    ground.publish("GLOBEX_1/heartbeats/out", b"secret")
    time.sleep(0.3)
    assert spy.received == []
    spy.stop()
    ground.stop()


def test_a_drone_cannot_take_another_drones_queued_commands(world_tx, rabbit):
    spy_creds = credentials.provision("ACME_1")
    victim_creds = credentials.provision("GLOBEX_1")
    victim = Peer(drone_url(victim_creds, 1), "GLOBEX_1", clean_session=False)
    victim.subscribe("GLOBEX_1/+/in")
    victim.stop()
    ground = ground_peer(rabbit, 1)
    ground.publish("GLOBEX_1/control/in", b"queued")
    time.sleep(0.3)
    # Resuming the victim's persistent session needs its session queue: refused.
    with pytest.raises(ConnectionRefusedError):
        Peer(drone_url(spy_creds, 2), "GLOBEX_1", clean_session=False)
    victim = Peer(drone_url(victim_creds, 2), "GLOBEX_1", clean_session=False)
    assert wait_for(lambda: ("GLOBEX_1/control/in", b"queued") in victim.received)
    victim.stop()
    ground.stop()


# -- revocation ---------------------------------------------------------------------------


def test_revocation_closes_the_live_connection_and_refuses_reconnects(world_tx, rabbit):
    issued = credentials.provision("ACME_1")
    drone = Peer(drone_url(issued, 2), "skyhive-agent-ACME_1", clean_session=False)
    drone.subscribe("ACME_1/+/in")
    admin = RabbitMQAdmin.from_settings()
    assert wait_for(lambda: admin.connections_of(["ACME_1"]))

    credentials.revoke(Drone.objects.get(drone_id="ACME_1"))

    assert drone.disconnected.wait(5), "RabbitMQ kept the revoked drone connected"
    drone.stop()
    for node in (1, 2):
        with pytest.raises(ConnectionRefusedError):
            Peer(drone_url(issued, node), "ACME_1")
    assert "ACME_1" not in [u["name"] for u in admin.users()]
    # Commands queued for it are gone too, so a later re-issue cannot replay them.
    assert admin.queues_named("^mqtt-subscription-.*ACME_1") == []
    assert Drone.objects.get(drone_id="ACME_1").credentials_revoked


def test_revocation_through_the_api_cuts_the_drone_off(world_tx, rabbit):
    owner = Client()
    owner.force_login(world_tx.owner)
    issued = owner.post("/api/v1/drones/ACME_1/credentials/")
    assert issued.status_code == 201
    urls = issued.json()["mqtt"]["urls"]
    drone = Peer(urls[0], "ACME_1")
    assert owner.delete("/api/v1/drones/ACME_1/credentials/").status_code == 204
    assert drone.disconnected.wait(5)
    drone.stop()
    with pytest.raises(ConnectionRefusedError):
        Peer(urls[1], "ACME_1")


# -- bulk and rebuild ---------------------------------------------------------------------


def test_provision_many_applies_a_batch_and_any_drone_of_it_connects(world_tx, rabbit):
    ids = [f"BATCH_{i:03d}" for i in range(60)]
    started = time.monotonic()
    issued = credentials.provision_many(ids, "acme")
    elapsed = time.monotonic() - started
    assert [c.drone_id for c in issued] == ids
    assert len({c.password for c in issued}) == len(ids)
    assert Drone.objects.filter(drone_id__in=ids, organisation__slug="acme").count() == len(ids)
    # Measured 0.15 s quiet and 0.29 s with four busy processes on two cores.
    assert elapsed < 10
    admin = RabbitMQAdmin.from_settings()
    users = {u["name"] for u in admin.users() if credentials.DRONE_TAG in u["tags"]}
    assert set(ids) <= users
    drone = Peer(issued[42].urls[1], ids[42])
    drone.subscribe(f"{ids[42]}/+/in")
    assert not drone.disconnected.is_set()
    drone.stop()


def test_provision_many_refuses_the_whole_batch_for_one_bad_entry(world_tx, rabbit):
    with pytest.raises(credentials.ProvisioningError, match="belongs to globex"):
        credentials.provision_many(["FRESH_1", "GLOBEX_1"], "acme")
    with pytest.raises(credentials.ProvisioningError, match="Invalid drone id"):
        credentials.provision_many(["FRESH_1", "bad id!"], "acme")
    with pytest.raises(credentials.ProvisioningError, match="twice"):
        credentials.provision_many(["FRESH_1", "FRESH_1"], "acme")
    assert not Drone.objects.filter(drone_id="FRESH_1").exists()
    admin = RabbitMQAdmin.from_settings()
    assert "FRESH_1" not in [u["name"] for u in admin.users()]


def test_sync_rebuilds_a_wiped_broker_from_the_database_and_removes_strays(world_tx, rabbit):
    kept = credentials.provision("ACME_1")
    credentials.provision("GLOBEX_1")
    admin = RabbitMQAdmin.from_settings()
    # A replaced cluster: our users are gone, and a stale drone user is left over.
    admin.delete_users(["ACME_1", "GLOBEX_1"])
    admin.put_user("STALE_1", rabbit_password_hash("old"), tags=[credentials.DRONE_TAG])
    # A drone issued before the RabbitMQ backend existed: only Mosquitto's hash.
    legacy = Drone.objects.get(drone_id="GLOBEX_1")
    legacy.mqtt_password_hash = credentials.hash_password("pw")
    legacy.save()

    out = io.StringIO()
    call_command("provision_drone", "--sync", stdout=out)
    report = json.loads(out.getvalue())

    # (Other tests of the session may have left drone users on the shared cluster: a
    # rebuild from this database removes them too.)
    assert "STALE_1" in report.pop("removed")
    assert report == {
        "broker": "rabbitmq",
        "users": 1,
        "needs_new_password": ["GLOBEX_1"],
        "reloaded": True,
    }
    names = {u["name"] for u in admin.users()}
    assert "ACME_1" in names and "STALE_1" not in names
    assert {"ground", "skyhive-admin"} <= names  # service users are never touched
    Peer(kept.urls[0], "ACME_1").stop()


def test_an_unreachable_broker_refuses_provisioning_and_keeps_the_old_password(
    world_tx, rabbit, settings
):
    first = credentials.provision("ACME_1")
    before = Drone.objects.get(drone_id="ACME_1").mqtt_password_hash
    settings.RABBITMQ_API_URLS = ["http://skyhive-admin:x@127.0.0.1:1/api"]
    with pytest.raises(credentials.BrokerUnavailable, match="no RabbitMQ node answered"):
        credentials.provision("ACME_1")
    assert Drone.objects.get(drone_id="ACME_1").mqtt_password_hash == before
    Peer(first.urls[1], "ACME_1").stop()


def test_a_revocation_the_broker_missed_is_finished_by_the_next_sync(world_tx, rabbit, settings):
    issued = credentials.provision("ACME_1")
    drone = Peer(issued.urls[0], "ACME_1")
    api_urls = settings.RABBITMQ_API_URLS
    settings.RABBITMQ_API_URLS = ["http://skyhive-admin:x@127.0.0.1:1/api"]
    with pytest.raises(credentials.BrokerUnavailable):
        credentials.revoke(Drone.objects.get(drone_id="ACME_1"))
    assert Drone.objects.get(drone_id="ACME_1").credentials_revoked  # the ground forgets it

    settings.RABBITMQ_API_URLS = api_urls
    assert "ACME_1" in credentials.sync_broker().removed
    assert drone.disconnected.wait(5)
    drone.stop()
    with pytest.raises(ConnectionRefusedError):
        Peer(issued.urls[1], "ACME_1")


def test_the_admin_client_falls_over_to_the_next_node_and_reports_refusals(rabbit):
    dead = "http://skyhive-admin:x@127.0.0.1:1/api"
    admin = RabbitMQAdmin([dead, *rabbit.api_urls], timeout=2)
    assert "ground" in [u["name"] for u in admin.users()]
    with pytest.raises(RabbitMQAdminError) as refused:
        admin.request("PUT", "users/bad", {"tags": "", "password_hash": "not base64!"})
    assert refused.value.status == 400


# -- health -------------------------------------------------------------------------------


def test_health_reports_each_node_and_is_degraded_but_up_while_one_answers(
    world_tx, rabbit, settings
):
    from django.contrib.auth.models import User

    from config import health

    staff = Client()
    staff.force_login(User.objects.create_user("operations", is_staff=True))
    health.forget()  # the checks are reused for a few seconds
    body = staff.get("/health").json()
    assert body["checks"]["broker"] == "ok" and body["status"] == "ok"
    assert body["broker_nodes"] == {f"127.0.0.1:{rabbit.mqtt_port(i)}": "ok" for i in (1, 2)}

    dead = "mqtt://ground:x@127.0.0.1:1"
    settings.MQTT_URLS = [rabbit.mqtt_urls[0], dead]
    health.forget()
    response = staff.get("/health")
    body = response.json()
    assert response.status_code == 200 and body["status"] == "degraded"
    assert body["checks"]["broker"].startswith("degraded: 127.0.0.1:1 down")
    assert body["broker_nodes"][f"127.0.0.1:{rabbit.mqtt_port(1)}"] == "ok"
    assert body["broker_nodes"]["127.0.0.1:1"] != "ok"

    settings.MQTT_URLS = [dead, "mqtt://ground:wrong@" + rabbit.mqtt_urls[1].split("@")[1]]
    health.forget()
    response = staff.get("/health")
    assert response.status_code == 503 and response.json()["status"] == "error"
    assert "refused" in response.json()["broker_nodes"][f"127.0.0.1:{rabbit.mqtt_port(2)}"]


# -- the Mosquitto backend's bulk path ----------------------------------------------------


def test_provision_many_on_mosquitto_rewrites_the_files_once_and_a_drone_connects(
    world_tx, settings, tmp_path
):
    directory = tmp_path / "mosquitto"
    broker = start_broker(
        directory,
        {"ground": "ground-pw"},
        extra_config=f"pid_file {directory / 'mosquitto.pid'}\n",
    )
    try:
        settings.MQTT_BROKER = "mosquitto"
        settings.MOSQUITTO_DIR = str(directory)
        settings.MQTT_URL = broker.url_for("ground")
        settings.MQTT_PUBLIC_HOST = "127.0.0.1"
        settings.MQTT_PUBLIC_PORT = broker.port
        ids = [f"MOSQ_{i:03d}" for i in range(40)]
        issued = credentials.provision_many(ids, "acme")
        passwd = (directory / "passwd").read_text().splitlines()
        assert passwd[0].startswith("ground:$7$")
        drone_lines = [line for line in passwd if line.startswith("MOSQ_")]
        assert len(drone_lines) == 40 and all(" " not in line for line in drone_lines)
        assert issued[7].urls == (f"mqtt://MOSQ_007:{issued[7].password}@127.0.0.1:{broker.port}",)
        ground = Peer(broker.url_for("ground"), "ground-mosq")
        ground.subscribe("MOSQ_007/+/out")
        drone = Peer(issued[7].urls[0], "MOSQ_007")
        drone.publish("MOSQ_007/heartbeats/out", b"beat")
        assert wait_for(lambda: ground.received)
        drone.stop()
        ground.stop()
        # A drone deleted behind the module's back leaves the files at the next rebuild.
        Drone.objects.filter(drone_id="MOSQ_039").delete()
        report = credentials.sync_broker()
        assert (report.broker, report.users, report.removed) == ("mosquitto", 39, ["MOSQ_039"])
        assert report.reloaded
    finally:
        broker.stop()
