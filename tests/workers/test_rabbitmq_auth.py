"""The drones' RabbitMQ auth service on its own: what it allows, what it remembers, and
what it refuses to read. The service against real nodes is in test_broker_sessions.py."""

from __future__ import annotations

import http.client
import threading
from collections.abc import Iterator
from urllib.parse import urlencode

import pytest

from runtime.processes import free_port
from workers.broker.rabbitmq_admin import RabbitMQAdmin, RabbitMQAdminError, rabbit_password_hash
from workers.broker.rabbitmq_auth import (
    MAX_BODY,
    PasswordHashes,
    allows,
    api_fetcher,
    build_server,
    rabbit_hash_matches,
)


class Hashes:
    """A table of drone hashes standing in for the cluster's global parameters, counting
    how often it is read."""

    def __init__(self, **hashes: str) -> None:
        self.hashes = dict(hashes)
        self.reads = 0

    def __call__(self, drone_id: str) -> str | None:
        self.reads += 1
        return self.hashes.get(drone_id)


def login(username: str, password: str, client_id: str) -> dict[str, str]:
    return {"username": username, "password": password, "client_id": client_id, "vhost": "/"}


def test_the_hash_check_is_rabbitmqs_salted_sha256():
    hashed = rabbit_password_hash("s3cret")
    assert rabbit_hash_matches("s3cret", hashed)
    assert not rabbit_hash_matches("s3cret!", hashed)
    assert not rabbit_hash_matches("s3cret", "not base64!")
    assert not rabbit_hash_matches("s3cret", "")


def test_only_the_drones_own_client_ids_with_its_password_are_allowed():
    hashes = PasswordHashes(Hashes(ACME_1=rabbit_password_hash("pw")))
    assert allows(login("ACME_1", "pw", "ACME_1"), hashes)
    assert allows(login("ACME_1", "pw", "skyhive-agent-ACME_1"), hashes)
    for client_id in ("GLOBEX_1", "skyhive-agent-GLOBEX_1", "gateway-h-0", "ACME_1x", ""):
        assert not allows(login("ACME_1", "pw", client_id), hashes), client_id
    assert not allows(login("ACME_1", "wrong", "ACME_1"), hashes)
    assert not allows(login("GLOBEX_1", "pw", "GLOBEX_1"), hashes)  # no hash: no drone
    assert not allows({"username": "ACME_1", "password": "pw"}, hashes)  # AMQP: no client id


def test_a_hash_is_read_once_per_period_and_a_new_password_works_at_once():
    table = Hashes(ACME_1=rabbit_password_hash("old"))
    now = [0.0]
    hashes = PasswordHashes(table, ttl=10, clock=lambda: now[0])
    assert allows(login("ACME_1", "old", "ACME_1"), hashes)
    assert allows(login("ACME_1", "old", "ACME_1"), hashes)
    assert table.reads == 1
    table.hashes["ACME_1"] = rabbit_password_hash("new")
    assert allows(login("ACME_1", "new", "ACME_1"), hashes)  # a mismatch reads again
    assert table.reads == 2
    assert not allows(login("ACME_1", "old", "ACME_1"), hashes)


def test_the_cache_keeps_at_most_its_bound():
    table = Hashes(**{f"D{i}": rabbit_password_hash("pw") for i in range(50)})
    hashes = PasswordHashes(table, entries=10)
    for i in range(50):
        assert allows(login(f"D{i}", "pw", f"D{i}"), hashes)
    assert len(hashes) == 10


def test_an_unreadable_hash_refuses_the_drone():
    dead = RabbitMQAdmin(["http://skyhive-admin:x@127.0.0.1:1/api"], timeout=1)
    hashes = PasswordHashes(api_fetcher(dead))
    with pytest.raises(RabbitMQAdminError):
        hashes.get("ACME_1")
    assert not allows(login("ACME_1", "pw", "ACME_1"), hashes)


@pytest.fixture
def service() -> Iterator[int]:
    port = free_port()
    server = build_server(port, PasswordHashes(Hashes(ACME_1=rabbit_password_hash("pw"))))
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield port
    server.shutdown()
    server.server_close()


def _post(port: int, path: str, body: bytes) -> tuple[int, str]:
    connection = http.client.HTTPConnection("127.0.0.1", port, timeout=5)
    connection.request("POST", path, body, {"content-type": "application/x-www-form-urlencoded"})
    response = connection.getresponse()
    answer = response.status, response.read().decode()
    connection.close()
    return answer


def test_the_service_answers_rabbitmqs_user_path_and_denies_the_rest(service):
    good = urlencode(login("ACME_1", "pw", "skyhive-agent-ACME_1")).encode()
    assert _post(service, "/auth/user", good) == (200, "allow")
    stolen = urlencode(login("ACME_1", "pw", "gateway-h-0")).encode()
    assert _post(service, "/auth/user", stolen) == (200, "deny")
    assert _post(service, "/auth/topic", good) == (200, "deny")


def test_the_service_refuses_a_body_over_its_bound_before_reading_it(service):
    assert _post(service, "/auth/user", b"x" * (MAX_BODY + 1)) == (413, "deny")
