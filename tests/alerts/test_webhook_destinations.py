"""Webhooks from the attacker's side: an organisation admin cannot point alerts at what
only the server reaches (its loopback, the cloud's metadata address, the site's private
network), a receiver cannot redirect them, and members below admin never read a webhook
URL. No test here sends a packet to an address that is not loopback: the refused
addresses are refused before any connection, which the interpreter's own audit events
(`socket.connect`) show."""

from __future__ import annotations

import sys
from collections.abc import Iterator
from contextlib import contextmanager
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from threading import Thread

import pytest
from django.test import Client
from rest_framework.test import APIClient

from accounts.models import OrganisationSettings
from alerts import delivery
from alerts.models import Delivery
from config import outbound
from tests.alerts.test_alerts import _recipients, critical_alarm

REFUSED_AT_SAVE = (
    "http://127.0.0.1:6379/",
    "http://[::1]:8000/hook",
    "https://10.0.0.1/hook",
    "http://169.254.169.254/latest/meta-data/",
    "http://localhost:5432/",
    "http://[::ffff:127.0.0.1]/hook",
    "http://224.0.0.1/hook",
)

_connects: list[object] | None = None


def _on_audit(event: str, args: tuple) -> None:
    if event == "socket.connect" and _connects is not None:
        _connects.append(args[1])


sys.addaudithook(_on_audit)  # hooks stay for the process: this one records only when asked


@contextmanager
def connections() -> Iterator[list[object]]:
    """Every address a socket of this process tries to connect to, meanwhile."""
    global _connects
    _connects = []
    try:
        yield _connects
    finally:
        _connects = None


def _form(recipients: str) -> dict[str, str]:
    return {"name": "Acme", "default_home": "", "alert_recipients": recipients}


def test_webhooks_to_loopback_private_link_local_and_multicast_are_refused_at_save(world):
    client = Client()
    client.force_login(world.owner)
    for url in REFUSED_AT_SAVE:
        with connections() as tried:
            response = client.post("/accounts/organisation/", _form(f"ops@example.org\n{url}"))
        assert response.status_code == 400, url
        assert "alert recipients" in response.content.decode()
        assert not [address for address in tried if isinstance(address, tuple)], url
    stored = OrganisationSettings.objects.filter(organisation=world.org).first()
    assert stored is None or stored.alert_recipients == []


def test_a_site_that_allows_private_receivers_saves_one_on_its_network(world, settings):
    settings.ALERT_WEBHOOK_ALLOW_PRIVATE = True
    client = Client()
    client.force_login(world.owner)
    url = "http://10.0.0.1/hook"
    assert client.post("/accounts/organisation/", _form(url)).status_code == 302
    assert OrganisationSettings.objects.get(organisation=world.org).alert_recipients == [url]
    metadata = _form("http://169.254.169.254/latest/meta-data/")
    assert client.post("/accounts/organisation/", metadata).status_code == 400


@pytest.mark.parametrize("url", ["http://10.0.0.1/hook", "http://169.254.169.254/latest/"])
def test_a_stored_webhook_to_a_refused_address_is_refused_again_before_any_connection(
    world, settings, url
):
    settings.ALERT_WEBHOOK_ALLOW_PRIVATE = url.startswith("http://169.254.")
    _recipients(world.org, url)
    critical_alarm(world.org, world.drone, "motor failure")
    item = Delivery.objects.get()
    with connections() as tried:
        assert delivery.attempt(str(item.pk)) == "retry"
    assert [address for address in tried if isinstance(address, tuple)] == []
    item.refresh_from_db()
    assert item.status == Delivery.Status.PENDING
    assert "refused" in item.last_error


class Receiver:
    """A real HTTP server on loopback answering `status` (with `location`, if any)."""

    def __init__(self, status: int = 200, location: str = "") -> None:
        self.requests: list[tuple[str, dict]] = []
        receiver = self

        class Handler(BaseHTTPRequestHandler):
            def _answer(self) -> None:
                self.rfile.read(int(self.headers.get("Content-Length") or 0))
                receiver.requests.append((self.path, dict(self.headers)))
                self.send_response(status)
                if location:
                    self.send_header("Location", location)
                self.send_header("Content-Length", "0")
                self.end_headers()

            do_GET = do_POST = _answer  # noqa: N815 - the http.server names

            def log_message(self, *args: object) -> None:
                return

        self.server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        Thread(target=self.server.serve_forever, daemon=True).start()
        self.url = f"http://127.0.0.1:{self.server.server_port}/hook?token=s3cret"

    def close(self) -> None:
        self.server.shutdown()
        self.server.server_close()


@pytest.fixture
def receiver() -> Iterator[type[Receiver]]:
    made: list[Receiver] = []

    def make(*args: object) -> Receiver:
        made.append(Receiver(*args))  # type: ignore[arg-type]
        return made[-1]

    yield make  # type: ignore[misc]
    for each in made:
        each.close()


def test_a_receiver_on_loopback_gets_alerts_only_when_the_site_allows_private(
    world, settings, receiver
):
    hook = receiver()
    _recipients(world.org, hook.url)
    critical_alarm(world.org, world.drone, "motor failure")
    item = Delivery.objects.get()
    assert delivery.attempt(str(item.pk)) == "retry"
    assert hook.requests == []
    settings.ALERT_WEBHOOK_ALLOW_PRIVATE = True
    assert delivery.attempt(str(item.pk)) == "delivered"
    [(path, headers)] = hook.requests
    assert path == "/hook?token=s3cret"
    assert headers["Host"] == f"127.0.0.1:{hook.server.server_port}"


def test_a_webhook_by_name_is_sent_with_its_host_name_to_the_address_checked(settings, receiver):
    settings.ALERT_WEBHOOK_ALLOW_PRIVATE = True
    hook = receiver()
    url = hook.url.replace("127.0.0.1", "localhost")
    assert outbound.post(url, b"{}", {}, timeout=5) == 200
    assert hook.requests[0][1]["Host"] == f"localhost:{hook.server.server_port}"


def test_a_receiver_that_answers_a_redirect_is_not_followed(world, settings, receiver):
    settings.ALERT_WEBHOOK_ALLOW_PRIVATE = True
    elsewhere = receiver()
    hook = receiver(302, elsewhere.url)
    _recipients(world.org, hook.url)
    critical_alarm(world.org, world.drone, "motor failure")
    item = Delivery.objects.get()
    assert delivery.attempt(str(item.pk)) == "retry"
    item.refresh_from_db()
    assert "302" in item.last_error and "not followed" in item.last_error
    assert len(hook.requests) == 1 and elsewhere.requests == []


def test_only_admins_read_webhook_urls_in_the_alerts_api(world):
    _recipients(world.org, "ops@example.org", "https://hooks.example.org/x?token=s3cret")
    critical_alarm(world.org, world.drone, "motor failure")
    client = APIClient()
    for user in (world.viewer, world.operator):
        client.force_authenticate(user)
        body = client.get("/api/v1/alerts/").content.decode()
        assert "ops@example.org" in body
        assert "hooks.example.org" not in body and "s3cret" not in body
    client.force_authenticate(world.owner)
    assert "hooks.example.org/x?token=s3cret" in client.get("/api/v1/alerts/").content.decode()


def test_only_admins_read_webhook_urls_in_the_audit_csv(world):
    owner = Client()
    owner.force_login(world.owner)
    url = "https://hooks.example.org/x?token=s3cret"
    assert owner.post("/accounts/organisation/", _form(url)).status_code == 302
    assert "hooks.example.org/x?token=s3cret" in _csv(owner)
    for user in (world.viewer, world.operator):
        member = Client()
        member.force_login(user)
        text = _csv(member)
        assert "organisation.change" in text
        assert "hooks.example.org" not in text and "s3cret" not in text


def _csv(client: Client) -> str:
    response = client.get("/accounts/audit.csv")
    assert response.status_code == 200
    return b"".join(response.streaming_content).decode()
