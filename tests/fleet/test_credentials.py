"""Per-drone broker credentials: provisioning, isolation and revocation on a real broker."""

from __future__ import annotations

import io
import json
import subprocess
import threading

import pytest
from django.core.management import call_command

from fleet import credentials
from fleet.models import Drone
from runtime.processes import wait_for

from .conftest import client_for, mqtt_client

pytestmark = pytest.mark.django_db(transaction=True)


def _provision_command(*args: str) -> dict:
    out = io.StringIO()
    call_command("provision_drone", *args, stdout=out)
    return json.loads(out.getvalue())


def test_provision_drone_creates_the_drone_and_prints_working_credentials(world_tx, broker):
    printed = _provision_command("NEW_7", "--org", "acme")
    assert printed["drone_id"] == "NEW_7"
    assert printed["mqtt"]["username"] == "NEW_7"
    assert (printed["mqtt"]["host"], printed["mqtt"]["port"]) == ("127.0.0.1", broker.port)
    drone = Drone.objects.get(drone_id="NEW_7")
    assert drone.organisation.slug == "acme"
    assert printed["mqtt"]["password"] not in drone.mqtt_password_hash
    client = mqtt_client(f"mqtt://NEW_7:{printed['mqtt']['password']}@127.0.0.1:{broker.port}")
    client.disconnect()
    client.loop_stop()


def test_each_provisioning_issues_a_new_password_and_the_old_one_stops_working(world_tx, broker):
    first = _provision_command("ACME_1")["mqtt"]["password"]
    second = _provision_command("ACME_1")["mqtt"]["password"]
    assert first != second
    with pytest.raises(ConnectionRefusedError):
        mqtt_client(f"mqtt://ACME_1:{first}@127.0.0.1:{broker.port}")
    mqtt_client(f"mqtt://ACME_1:{second}@127.0.0.1:{broker.port}").loop_stop()


def test_provisioning_refuses_to_move_a_drone_to_another_organisation(world_tx, broker):
    from django.core.management.base import CommandError

    with pytest.raises(CommandError, match="belongs to acme"):
        _provision_command("ACME_1", "--org", "globex")
    with pytest.raises(CommandError):
        _provision_command("bad id!", "--org", "acme")


def test_our_hash_is_the_one_mosquitto_passwd_writes(tmp_path):
    passwd = tmp_path / "passwd"
    passwd.write_text("")
    subprocess.run(["mosquitto_passwd", "-b", str(passwd), "u", "s3cret"], check=True)
    hashed = passwd.read_text().strip().split(":", 1)[1]
    assert credentials.check_password("s3cret", hashed)
    assert not credentials.check_password("wrong", hashed)
    ours = credentials.hash_password("s3cret")
    assert ours.startswith("$7$101$") and credentials.check_password("s3cret", ours)


def test_the_regenerated_files_keep_the_ground_user(world_tx, broker):
    credentials.provision("ACME_1")
    passwd = (broker.directory / "passwd").read_text()
    assert passwd.startswith("ground:$7$")
    assert "\nACME_1:$7$" in passwd
    mqtt_client(broker.url_for("ground")).loop_stop()


def test_a_drone_cannot_publish_on_another_drones_topics(world_tx, broker, gateway):
    acme = credentials.provision("ACME_1")
    globex = credentials.provision("GLOBEX_1")
    spy = mqtt_client(f"mqtt://ACME_1:{acme.password}@127.0.0.1:{broker.port}")
    listener = mqtt_client(broker.url_for("ground"))
    seen: list[str] = []
    listener.on_message = lambda c, u, m: seen.append(m.topic)
    listener.subscribe("#")
    victim = mqtt_client(f"mqtt://GLOBEX_1:{globex.password}@127.0.0.1:{broker.port}")
    commands: list[bytes] = []
    victim.on_message = lambda c, u, m: commands.append(m.payload)
    victim.subscribe("GLOBEX_1/control/in")
    # Reading another drone's commands is refused per message too.
    spy_inbox: list[str] = []
    spy.on_message = lambda c, u, m: spy_inbox.append(m.topic)
    spy.subscribe("GLOBEX_1/control/in")
    wait_for(lambda: False, 0.2)

    spy.publish("GLOBEX_1/heartbeats/out", b"{}", qos=1).wait_for_publish(2)
    spy.publish("GLOBEX_1/control/in", b'{"command": "disarm"}', qos=1).wait_for_publish(2)
    spy.publish("ACME_1/heartbeats/out", b"{}", qos=1).wait_for_publish(2)
    listener.publish("GLOBEX_1/control/in", b"{}", qos=1).wait_for_publish(2)
    assert wait_for(lambda: "ACME_1/heartbeats/out" in seen and commands)
    assert "GLOBEX_1/heartbeats/out" not in seen
    assert commands == [b"{}"]  # only the ground's message reached the victim
    assert spy_inbox == []
    for client in (spy, listener, victim):
        client.loop_stop()


def test_revoking_through_the_api_cuts_the_drone_off(world_tx, broker):
    owner = client_for(world_tx.owner)
    issued = owner.post("/api/v1/drones/ACME_1/credentials/")
    assert issued.status_code == 201
    password = issued.json()["mqtt"]["password"]
    drone = mqtt_client(f"mqtt://ACME_1:{password}@127.0.0.1:{broker.port}")
    gone = threading.Event()
    drone.on_disconnect = lambda *args: gone.set()
    drone.reconnect_delay_set(60, 60)

    assert owner.delete("/api/v1/drones/ACME_1/credentials/").status_code == 204
    assert gone.wait(5), "the broker kept the revoked drone connected"
    assert Drone.objects.get(drone_id="ACME_1").credentials_revoked
    with pytest.raises(ConnectionRefusedError):
        mqtt_client(f"mqtt://ACME_1:{password}@127.0.0.1:{broker.port}")
    drone.loop_stop()


def test_only_admins_manage_credentials(world_tx, broker):
    operator = client_for(world_tx.operator)
    assert operator.post("/api/v1/drones/ACME_1/credentials/").status_code == 403
    outsider = client_for(world_tx.outsider)
    assert outsider.post("/api/v1/drones/ACME_1/credentials/").status_code == 404


def test_the_admin_shows_gateway_counters_and_issues_and_revokes_credentials(world_tx, broker):
    from django.contrib.auth import get_user_model

    from workers.counters import Counters

    counters = Counters("gateway-admin-test")
    counters.incr("dropped.malformed", 3)
    counters.flush()
    admin_user = get_user_model().objects.create_superuser("root", "r@example.com", "pw")
    client = client_for(admin_user)
    page = client.get("/admin/fleet/drone/").content.decode()
    assert "gateway-admin-test" in page and "dropped.malformed" in page

    pk = Drone.objects.get(drone_id="ACME_1").pk
    issued = client.post(
        "/admin/fleet/drone/",
        {"action": "issue_credentials", "_selected_action": [pk]},
        follow=True,
    ).content.decode()
    assert "&quot;password&quot;" in issued
    assert Drone.objects.get(pk=pk).mqtt_password_hash.startswith("$7$")
    client.post("/admin/fleet/drone/", {"action": "revoke_credentials", "_selected_action": [pk]})
    assert Drone.objects.get(pk=pk).credentials_revoked
