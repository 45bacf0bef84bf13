"""RabbitMQ's HTTP authentication service: a drone logs in only under its own client id.

RabbitMQ 3.10's MQTT plugin registers a client id cluster-wide, keyed by the id alone,
right after login: whoever logs in with an id in use disconnects its holder. Its internal
auth backend never sees the id, but the MQTT plugin hands it to every auth backend as
`client_id` (`rabbit_mqtt_connection_info:additional_authn_params`, passed on by
`rabbit_direct:auth_fun`), and `rabbitmq_auth_backend_http` posts it to this service with
the username and password.

scripts/rabbitmq.sh configures each node with two backends, tried in order:

1. `internal`: the ground's service users (`ground`, `skyhive-admin`), whose passwords
   RabbitMQ holds. Drone users have no password there (an empty hash never matches), so
   a drone always falls through to
2. `authn = http` (this service) with `authz = internal`: the drone's password is
   checked here, and its client id must be its own (`drone_client_ids`); permissions,
   tags and whether the user exists at all stay RabbitMQ's own (a deleted user is refused
   by the internal authz whatever this service says).

The drone's password hash (RabbitMQ's salted SHA-256, as provisioning stores it) is kept
in a global runtime parameter of the cluster (`password_parameter`), written and removed
with the user by workers.broker.credentials.RabbitMQBackend through the management API.
This service reads it through the same API, as the admin user (authenticated by the
internal backend, so no login of ours waits on itself).

Cost and bounds: one HTTP call from the node per drone login (never per message), and at
most one management API call per drone per CACHE_SECONDS; a request body is at most
MAX_BODY bytes. The node waits at most `auth_http.request_timeout` (rabbitmq.sh) for an
answer; when this service is down, slow or cannot reach the API, drones are refused
(fail closed) and retry, while the ground's logins never reach it.
"""

from __future__ import annotations

import argparse
import base64
import binascii
import hashlib
import logging
import os
import secrets
import threading
import time
from collections import OrderedDict
from collections.abc import Callable, Sequence
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from urllib.parse import parse_qs, quote

from .rabbitmq_admin import RabbitMQAdmin, RabbitMQAdminError

log = logging.getLogger(__name__)

PARAMETER_PREFIX = "skyhive-drone-password."
AGENT_CLIENT_ID_PREFIX = "skyhive-agent-"
CACHE_SECONDS = 10.0  # a re-issued password's predecessor is accepted this long at most
CACHE_ENTRIES = 10_000
MAX_BODY = 4096  # username, password, vhost and client id; MQTT limits each to 64 KiB
API_TIMEOUT = 1.5  # per management API node; the node's own wait is request_timeout
API_URLS_ENV = "RABBITMQ_AUTH_API_URLS"


def password_parameter(drone_id: str) -> str:
    """The global runtime parameter holding the drone's password hash."""
    return f"{PARAMETER_PREFIX}{drone_id}"


def drone_client_ids(drone_id: str) -> tuple[str, str]:
    """The client ids a drone account may use: its id (load drones, the onboard bridge)
    and the onboard agent's `skyhive-agent-<id>`; the same two its session queues are
    named after (workers.broker.credentials.session_queue_pattern)."""
    return drone_id, f"{AGENT_CLIENT_ID_PREFIX}{drone_id}"


def rabbit_hash_matches(password: str, password_hash: str) -> bool:
    """RabbitMQ's rabbit_password_hashing_sha256: base64(salt(4) ++ sha256(salt ++ pw))."""
    try:
        raw = base64.b64decode(password_hash, validate=True)
    except (binascii.Error, ValueError):
        return False
    if len(raw) != 4 + hashlib.sha256().digest_size:
        return False
    salt, digest = raw[:4], raw[4:]
    return secrets.compare_digest(hashlib.sha256(salt + password.encode()).digest(), digest)


# -- where the hashes come from -------------------------------------------------------


class PasswordHashes:
    """Drone password hashes read from the cluster's global parameters, kept for
    CACHE_SECONDS (at most CACHE_ENTRIES drones). A missing drone is not remembered, so a
    newly provisioned one logs in at once."""

    def __init__(
        self,
        fetch: Callable[[str], str | None],
        *,
        ttl: float = CACHE_SECONDS,
        entries: int = CACHE_ENTRIES,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.fetch = fetch
        self.ttl = ttl
        self.entries = entries
        self.clock = clock
        self._cache: OrderedDict[str, tuple[str, float]] = OrderedDict()
        self._lock = threading.Lock()

    def __len__(self) -> int:
        return len(self._cache)

    def get(self, drone_id: str, *, fresh: bool = False) -> tuple[str | None, bool]:
        """The hash and whether it came from the cache."""
        now = self.clock()
        with self._lock:
            cached = self._cache.get(drone_id)
            if cached and not fresh and now - cached[1] < self.ttl:
                self._cache.move_to_end(drone_id)
                return cached[0], True
        found = self.fetch(drone_id)
        with self._lock:
            if found is None:
                self._cache.pop(drone_id, None)
            else:
                self._cache[drone_id] = (found, now)
                self._cache.move_to_end(drone_id)
                while len(self._cache) > self.entries:
                    self._cache.popitem(last=False)
        return found, False


def api_fetcher(admin: RabbitMQAdmin) -> Callable[[str], str | None]:
    """Reads `password_parameter(drone_id)`; None when there is none. Any other failure
    raises RabbitMQAdminError, which refuses the login."""

    def fetch(drone_id: str) -> str | None:
        name = quote(password_parameter(drone_id), safe="")
        try:
            parameter = admin.request("GET", f"global-parameters/{name}")
        except RabbitMQAdminError as exc:
            if exc.status == 404:
                return None
            raise
        value = (parameter or {}).get("value") or {}
        hashed = value.get("password_hash") if isinstance(value, dict) else None
        return hashed if isinstance(hashed, str) and hashed else None

    return fetch


# -- the decision -------------------------------------------------------------------------


def allows(form: dict[str, str], hashes: PasswordHashes) -> bool:
    """Whether `user_path`'s form (username, password, client_id) is a drone logging in
    under one of its own client ids with its password. No client id (an AMQP, stream or
    management login) is refused: drones use MQTT only."""
    username = form.get("username", "")
    password = form.get("password", "")
    client_id = form.get("client_id", "")
    if not username or not password or not client_id:
        return False
    if client_id not in drone_client_ids(username):
        log.warning("refused %s: client id %r is not its own", username, client_id)
        return False
    try:
        hashed, cached = hashes.get(username)
        if hashed is not None and rabbit_hash_matches(password, hashed):
            return True
        if cached:  # a password re-issued since the hash was read
            hashed, _ = hashes.get(username, fresh=True)
            return hashed is not None and rabbit_hash_matches(password, hashed)
    except RabbitMQAdminError as exc:
        log.error("refused %s: its password hash could not be read: %s", username, exc)
    return False


# -- the HTTP service ---------------------------------------------------------------------


class AuthHandler(BaseHTTPRequestHandler):
    """`POST /auth/user` answers `allow` or `deny`; the authz paths are never configured
    (authz is the internal backend) and are denied; `GET /health` answers `ok`."""

    hashes: PasswordHashes  # set on the subclass serve() builds
    timeout = 5  # a stalled request holds a thread at most this long
    protocol_version = "HTTP/1.1"

    def do_GET(self) -> None:  # noqa: N802 (http.server's naming)
        if self.path == "/health":
            self._answer(200, "ok")
        else:
            self._answer(404, "not found")

    def do_POST(self) -> None:  # noqa: N802
        try:
            length = int(self.headers.get("content-length") or 0)
        except ValueError:
            length = -1
        if not 0 <= length <= MAX_BODY:
            self._answer(413, "deny", close=True)
            return
        body = self.rfile.read(length).decode("utf-8", "replace")
        if self.path != "/auth/user":
            self._answer(200, "deny")
            return
        form = {key: values[0] for key, values in parse_qs(body).items()}
        self._answer(200, "allow" if allows(form, self.hashes) else "deny")

    def _answer(self, status: int, text: str, *, close: bool = False) -> None:
        payload = text.encode()
        self.send_response(status)
        self.send_header("content-type", "text/plain")
        self.send_header("content-length", str(len(payload)))
        if close:
            self.send_header("connection", "close")
            self.close_connection = True
        self.end_headers()
        self.wfile.write(payload)

    def log_message(self, format: str, *args: object) -> None:  # noqa: A002
        log.debug("%s " + format, self.address_string(), *args)


def build_server(port: int, hashes: PasswordHashes) -> ThreadingHTTPServer:
    """Bound to loopback only: the nodes it serves run on this host."""
    handler = type("BoundAuthHandler", (AuthHandler,), {"hashes": hashes})
    server = ThreadingHTTPServer(("127.0.0.1", port), handler)
    server.daemon_threads = True
    return server


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--port", type=int, required=True)
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(levelname)s %(message)s")
    # From the environment, not the command line: other users can read a process's
    # arguments, not its environment.
    api_urls = [u for u in os.environ.get(API_URLS_ENV, "").split(",") if u]
    admin = RabbitMQAdmin(api_urls, timeout=API_TIMEOUT)
    server = build_server(args.port, PasswordHashes(api_fetcher(admin)))
    log.info("RabbitMQ auth service on 127.0.0.1:%s", args.port)
    server.serve_forever()


if __name__ == "__main__":
    main()
