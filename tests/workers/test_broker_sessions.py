"""Broker sessions belong to their account: the attacker's side, on real brokers.

Mosquitto as scripts/services.sh starts it: the ground's processes on a listener of their
own, drones on theirs, where the client id is the username. Two drone accounts and the
gateway: a drone that asks for another's client id gets its own, the victim stays
connected and keeps its queued QoS 1 messages. On RabbitMQ 3.10 (the real two-node
cluster scripts/rabbitmq.sh starts) the nodes' auth service refuses a drone that asks for
another account's client id, and the holder stays connected; another account's session
queue is refused too. See docs/security.md ("Broker sessions").
"""

from __future__ import annotations

import io
import json
import os
import pwd
import shutil
import signal
import socket
import stat
import subprocess
import tempfile
import threading
import time
import uuid
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest
from django.core.management import call_command

from fleet import credentials
from fleet.models import Drone
from runtime.processes import free_port, wait_for
from workers.broker.credentials import DRONE_TAG, MosquittoBackend, rabbitmq_hash, stored_hash
from workers.broker.rabbitmq_admin import RabbitMQAdmin, rabbit_password_hash
from workers.broker.rabbitmq_auth import password_parameter

from .test_rabbitmq_credentials import Peer, drone_url, ground_peer, rabbit  # noqa: F401

ROOT = Path(__file__).resolve().parents[2]
SERVICES = ROOT / "scripts" / "services.sh"
DRONES = {"ACME_1": "acme-secret", "GLOBEX_1": "globex-secret"}


# -- Mosquitto, configured by scripts/services.sh -----------------------------------------


@dataclass
class Profile:
    data: Path
    env: dict[str, str]
    ground_port: int
    drone_port: int

    def secret(self, name: str) -> str:
        return (self.data / "secrets" / name).read_text()

    def ground_url(self) -> str:
        return f"mqtt://ground:{self.secret('mqtt_ground_password')}@127.0.0.1:{self.ground_port}"

    def drone_url(self, drone_id: str, port: int | None = None) -> str:
        return f"mqtt://{drone_id}:{DRONES[drone_id]}@127.0.0.1:{port or self.drone_port}"


def _services(profile: Profile, action: str, user: str | None = None) -> None:
    command = [str(SERVICES), action, "test"]
    if user is not None:  # as an unprivileged user: the files are then its own
        gid = pwd.getpwnam(user).pw_gid
        command = ["setpriv", f"--reuid={user}", f"--regid={gid}", "--clear-groups", *command]
    subprocess.run(command, env=profile.env, check=True, capture_output=True, timeout=60)


def _profile(data: Path) -> Profile:
    ground, drones = free_port(), free_port()
    env = {**os.environ, "DATA_DIR": str(data), "TEST_MQTT_PORT": str(ground),
           "TEST_MQTT_DRONE_PORT": str(drones)}  # fmt: skip
    return Profile(data, env, ground, drones)


@pytest.fixture
def mosquitto(tmp_path: Path) -> Iterator[Profile]:
    """Mosquitto started by services.sh, with two provisioned drones."""
    profile = _profile(tmp_path / "profile")
    _services(profile, "mosquitto-start")
    try:
        drones = [(drone_id, stored_hash(pw)) for drone_id, pw in DRONES.items()]
        directory = profile.data / "mosquitto"
        assert MosquittoBackend(directory, lambda: drones).sync(drones).reloaded
        # The reload is a signal: Mosquitto reads the new password file a moment later.
        assert wait_for(lambda: _accepted(profile.drone_url("GLOBEX_1")), 10)
        yield profile
    finally:
        _services(profile, "mosquitto-stop")


def _accepted(url: str) -> bool:
    try:
        Peer(url, f"probe-{uuid.uuid4().hex[:6]}").stop()
    except ConnectionRefusedError:
        return False
    return True


def _gone(peer: Peer) -> bool:
    return peer.disconnected.wait(1.0)


def test_a_drone_asking_for_another_drones_client_id_gets_its_own(mosquitto):
    victim = Peer(mosquitto.drone_url("ACME_1"), "skyhive-agent-ACME_1", clean_session=False)
    victim.subscribe("ACME_1/+/in")
    attacker = Peer(mosquitto.drone_url("GLOBEX_1"), "skyhive-agent-ACME_1")
    attacker.subscribe("GLOBEX_1/+/in")
    ground = Peer(mosquitto.ground_url(), f"web-test-{uuid.uuid4().hex[:6]}")
    assert not _gone(victim)
    ground.publish("ACME_1/control/in", b"for the victim")
    ground.publish("GLOBEX_1/control/in", b"for the attacker")
    assert wait_for(lambda: victim.received and attacker.received, 5)
    assert victim.topics() == ["ACME_1/control/in"]
    assert attacker.topics() == ["GLOBEX_1/control/in"]
    for peer in (victim, attacker, ground):
        peer.stop()


def test_a_drone_cannot_wipe_another_drones_queued_commands(mosquitto):
    victim = Peer(mosquitto.drone_url("ACME_1"), "ACME_1", clean_session=False)
    victim.subscribe("ACME_1/+/in")
    victim.stop()
    ground = Peer(mosquitto.ground_url(), f"web-test-{uuid.uuid4().hex[:6]}")
    ground.publish("ACME_1/control/in", b"queued")
    time.sleep(0.3)
    # A clean session under the victim's id would drop what is queued for it.
    Peer(mosquitto.drone_url("GLOBEX_1"), "ACME_1").stop()
    victim = Peer(mosquitto.drone_url("ACME_1"), "ACME_1", clean_session=False)
    assert wait_for(lambda: ("ACME_1/control/in", b"queued") in victim.received, 5)
    victim.stop()
    ground.stop()


def test_no_drone_reaches_the_gateways_session_or_its_queued_messages(mosquitto):
    gateway_id = f"gateway-{uuid.uuid4().hex[:6]}-0"
    gateway = Peer(mosquitto.ground_url(), gateway_id, clean_session=False)
    gateway.subscribe("+/alarms/out")
    drone = Peer(mosquitto.drone_url("ACME_1"), "ACME_1")
    # The ground's own listener refuses drone accounts, whatever the client id.
    with pytest.raises(ConnectionRefusedError):
        Peer(mosquitto.drone_url("GLOBEX_1", mosquitto.ground_port), gateway_id)
    attacker = Peer(mosquitto.drone_url("GLOBEX_1"), gateway_id)  # clean session
    assert not _gone(gateway)
    drone.publish("ACME_1/alarms/out", b"live")
    assert wait_for(lambda: ("ACME_1/alarms/out", b"live") in gateway.received, 5)
    gateway.stop()
    drone.publish("ACME_1/alarms/out", b"queued")
    time.sleep(0.3)
    attacker.stop()
    Peer(mosquitto.drone_url("GLOBEX_1"), gateway_id).stop()
    gateway = Peer(mosquitto.ground_url(), gateway_id, clean_session=False)
    assert wait_for(lambda: ("ACME_1/alarms/out", b"queued") in gateway.received, 5)
    for peer in (gateway, drone):
        peer.stop()


def test_provisioning_refuses_a_drone_id_shaped_like_a_ground_client_id():
    for drone_id in ("gateway-web1-0", "Web-web1-42-abcdef", "auto-1234"):
        with pytest.raises(credentials.ProvisioningError, match="ground's client ids"):
            credentials.provision(drone_id, "acme")


# -- secrets are created unreadable to others ---------------------------------------------


def _others_may_read(path: Path) -> bool:
    return bool(path.stat().st_mode & (stat.S_IROTH | stat.S_IWOTH))


@pytest.mark.skipif(os.geteuid() != 0 or shutil.which("setpriv") is None, reason="needs root")
def test_services_sh_creates_the_brokers_secrets_for_its_user_only():
    """As an unprivileged user (no later chmod to its broker's group): 0600 from the start."""
    data = Path(tempfile.mkdtemp(prefix="skyhive-modes-", dir="/tmp"))
    nobody = pwd.getpwnam("nobody")
    os.chown(data, nobody.pw_uid, nobody.pw_gid)
    data.chmod(0o700)
    profile = _profile(data / "profile")
    try:
        _services(profile, "mosquitto-start", user="nobody")
        broker = profile.data / "mosquitto"
        for path in [*(broker / n for n in ("passwd", "acl", "ground.passwd")),
                     *(profile.data / "secrets").iterdir()]:  # fmt: skip
            assert stat.S_IMODE(path.stat().st_mode) == 0o600, path
    finally:
        _services(profile, "mosquitto-stop", user="nobody")
        shutil.rmtree(data, ignore_errors=True)


def test_services_sh_as_root_opens_the_brokers_files_to_its_group_only(mosquitto):
    broker = mosquitto.data / "mosquitto"
    for name in ("passwd", "acl", "ground.passwd"):
        assert not _others_may_read(broker / name), name
    for path in (mosquitto.data / "secrets").iterdir():
        assert stat.S_IMODE(path.stat().st_mode) == 0o600, path


@pytest.mark.skipif(os.geteuid() != 0, reason="initdb runs as postgres only under root")
def test_the_database_superuser_password_file_is_never_readable_by_others():
    """Watched while initdb runs: the temporary password file is 0600 (postgres's) throughout."""
    watched = Path(tempfile.mkdtemp(prefix="skyhive-tmp-", dir="/tmp"))
    watched.chmod(0o711)  # postgres may reach a file given to it, not list the folder
    data = Path(tempfile.mkdtemp(prefix="skyhive-pg-", dir="/tmp"))
    data.chmod(0o755)
    seen: dict[str, int] = {}
    done = threading.Event()

    def watch() -> None:
        while not done.is_set():
            for entry in os.scandir(watched):
                try:
                    seen[entry.name] = seen.get(entry.name, 0) | entry.stat().st_mode
                except FileNotFoundError:
                    pass
            time.sleep(0.001)

    watcher = threading.Thread(target=watch, daemon=True)
    watcher.start()
    env = {**os.environ, "DATA_DIR": str(data), "TMPDIR": str(watched),
           "TEST_PG_PORT": str(free_port())}  # fmt: skip
    try:
        subprocess.run([str(SERVICES), "pg-start", "test"], env=env, check=True,
                       capture_output=True, timeout=180)  # fmt: skip
    finally:
        done.set()
        watcher.join()
        subprocess.run([str(SERVICES), "pg-stop", "test"], env=env, capture_output=True)
        shutil.rmtree(data, ignore_errors=True)
        shutil.rmtree(watched, ignore_errors=True)
    assert seen, "the password file was never seen"
    assert all(stat.S_IMODE(mode) & 0o077 == 0 for mode in seen.values()), seen


# -- RabbitMQ: the client id is bound to the account by the nodes' auth service -----------


def _rabbit_gateway_id() -> str:
    return f"gateway-{uuid.uuid4().hex[:6]}-0"


@pytest.mark.django_db(transaction=True)
def test_on_rabbitmq_a_drone_asking_for_another_accounts_client_id_is_refused_and_the_holder_stays(
    world_tx,
    rabbit,  # noqa: F811
):
    victim_creds = credentials.provision("ACME_1")
    attacker_creds = credentials.provision("GLOBEX_1")
    gateway_id = _rabbit_gateway_id()
    gateway = Peer(rabbit.mqtt_urls[0], gateway_id, clean_session=False)
    gateway.subscribe("+/alarms/out")
    publisher_id = f"web-test-{uuid.uuid4().hex[:6]}"
    publisher = Peer(rabbit.mqtt_urls[1], publisher_id)
    victim = Peer(drone_url(victim_creds, 2), "skyhive-agent-ACME_1", clean_session=False)
    victim.subscribe("ACME_1/+/in")
    stolen_ids = ["skyhive-agent-ACME_1", "ACME_1", gateway_id, publisher_id]
    for node in (1, 2):
        for stolen in stolen_ids:
            with pytest.raises(ConnectionRefusedError, match=REFUSED):
                Peer(drone_url(attacker_creds, node), stolen)
        with pytest.raises(ConnectionRefusedError, match=REFUSED):  # the broker makes one up
            Peer(drone_url(attacker_creds, node), "")
    for holder in (gateway, publisher, victim):
        assert not _gone(holder)
    # Each holder's link still works, and the attacker flies under its own ids.
    attacker = Peer(drone_url(attacker_creds, 1), "skyhive-agent-GLOBEX_1")
    attacker.subscribe("GLOBEX_1/+/in")
    publisher.publish("ACME_1/control/in", b"for the victim")
    publisher.publish("GLOBEX_1/control/in", b"for the attacker")
    victim.publish("ACME_1/alarms/out", b"alarm")
    assert wait_for(lambda: ("ACME_1/control/in", b"for the victim") in victim.received, 5)
    assert wait_for(lambda: ("GLOBEX_1/control/in", b"for the attacker") in attacker.received, 5)
    assert wait_for(lambda: ("ACME_1/alarms/out", b"alarm") in gateway.received, 5)
    assert victim.topics() == ["ACME_1/control/in"]
    for peer in (gateway, publisher, victim, attacker):
        peer.stop()


@pytest.mark.django_db(transaction=True)
def test_on_rabbitmq_a_drone_cannot_take_or_wipe_another_accounts_session(world_tx, rabbit):  # noqa: F811
    """Neither resuming another account's persistent session nor wiping it with a clean
    one gets through: the client id is refused at login, and the session queue needs
    permissions only its own account has. What was queued for the holders stays."""
    victim_creds = credentials.provision("ACME_1")
    attacker_creds = credentials.provision("GLOBEX_1")
    gateway_id = _rabbit_gateway_id()
    gateway = Peer(rabbit.mqtt_urls[0], gateway_id, clean_session=False)
    gateway.subscribe("+/alarms/out")
    victim = Peer(drone_url(victim_creds, 1), "ACME_1", clean_session=False)
    victim.subscribe("ACME_1/+/in")
    victim.stop()
    gateway.stop()
    ground = ground_peer(rabbit, 1)
    ground.publish("ACME_1/control/in", b"queued command")
    sender = Peer(drone_url(victim_creds, 2), "skyhive-agent-ACME_1")
    sender.publish("ACME_1/alarms/out", b"queued alarm")
    time.sleep(0.5)
    for stolen in ("ACME_1", gateway_id):
        for clean in (True, False):
            with pytest.raises(ConnectionRefusedError):
                Peer(drone_url(attacker_creds, 2), stolen, clean_session=clean)
    victim = Peer(drone_url(victim_creds, 1), "ACME_1", clean_session=False)
    gateway = Peer(rabbit.mqtt_urls[1], gateway_id, clean_session=False)
    assert wait_for(lambda: ("ACME_1/control/in", b"queued command") in victim.received, 5)
    assert wait_for(lambda: ("ACME_1/alarms/out", b"queued alarm") in gateway.received, 5)
    for peer in (victim, gateway, ground, sender):
        peer.stop()


@pytest.mark.django_db(transaction=True)
def test_on_rabbitmq_drones_are_refused_while_the_auth_service_is_down_or_silent_and_the_ground_is_not(
    world_tx,
    rabbit,  # noqa: F811
):
    """Fail closed for drones: node 1's auth service stopped, then a listener on its port
    that never answers (the node gives up after auth_http.request_timeout). The ground's
    logins never reach it; node 2, whose service runs, still takes the drone."""
    creds = credentials.provision("ACME_1")
    pid_file = ROOT / ".data" / rabbit.profile / "rabbitmq" / "1" / "auth.pid"
    os.kill(int(pid_file.read_text()), signal.SIGTERM)
    assert wait_for(lambda: not _port_open(rabbit.port_base + 41), 5)
    try:
        with pytest.raises(ConnectionRefusedError, match=REFUSED):
            Peer(drone_url(creds, 1), "ACME_1")
        Peer(rabbit.mqtt_urls[0], f"web-test-{uuid.uuid4().hex[:6]}").stop()
        Peer(drone_url(creds, 2), "ACME_1").stop()
        with socket.create_server(("127.0.0.1", rabbit.port_base + 41)) as silent:
            silent.settimeout(10)
            with pytest.raises(ConnectionRefusedError, match=REFUSED):
                Peer(drone_url(creds, 1), "ACME_1", connect_timeout=15)
            asked, _ = silent.accept()  # the node did ask, and got no answer
            asked.close()
            Peer(rabbit.mqtt_urls[0], f"web-test-{uuid.uuid4().hex[:6]}").stop()
    finally:
        rabbit.start_node(1)  # starts the node's auth service again
    Peer(drone_url(creds, 1), "ACME_1").stop()


@pytest.mark.django_db(transaction=True)
def test_on_rabbitmq_drone_users_left_with_a_password_of_their_own_are_upgraded_at_start(
    world_tx,
    rabbit,  # noqa: F811
):
    """A cluster provisioned before the auth service checked client ids keeps each drone's
    password in its user, where the internal backend logs it in under any client id. The
    ground's start (`provision_drone --upgrade`, run by `make run`) moves the hash to its
    parameter with the same password, removes an outdated user the database no longer
    has, and changes nothing the second time."""
    victim_creds = credentials.provision("ACME_1")
    old_creds = credentials.provision("GLOBEX_1")
    admin = RabbitMQAdmin.from_settings()
    stored = Drone.objects.get(drone_id="GLOBEX_1").mqtt_password_hash
    admin.put_user("GLOBEX_1", rabbitmq_hash(stored), tags=[DRONE_TAG])
    admin.delete_global_parameter(password_parameter("GLOBEX_1"))
    admin.put_user("STALE_1", rabbit_password_hash("old"), tags=[DRONE_TAG])
    # The earlier form bypasses the client-id check: this is what the start must close.
    Peer(drone_url(old_creds, 1), f"not-mine-{uuid.uuid4().hex[:6]}").stop()

    upgraded = _upgrade()

    assert {"GLOBEX_1", "STALE_1"} <= set(upgraded) and "ACME_1" not in upgraded
    users = {user["name"]: user for user in admin.users()}
    assert "STALE_1" not in users and users["GLOBEX_1"]["password_hash"] == ""
    victim = Peer(drone_url(victim_creds, 2), "skyhive-agent-ACME_1")
    for node in (1, 2):
        for stolen in ("skyhive-agent-ACME_1", f"not-mine-{uuid.uuid4().hex[:6]}"):
            with pytest.raises(ConnectionRefusedError, match=REFUSED):
                Peer(drone_url(old_creds, node), stolen)
        Peer(drone_url(old_creds, node), "skyhive-agent-GLOBEX_1").stop()  # same password
    assert not _gone(victim)
    victim.stop()
    assert not {"ACME_1", "GLOBEX_1", "STALE_1"} & set(_upgrade())


def _upgrade() -> list[str]:
    out = io.StringIO()
    call_command("provision_drone", "--upgrade", stdout=out)
    return json.loads(out.getvalue())["upgraded"]


# A CONNACK refusing the login (not a connection that timed out).
REFUSED = "Bad user name or password"


def _port_open(port: int) -> bool:
    with socket.socket() as probe:
        return probe.connect_ex(("127.0.0.1", port)) == 0
