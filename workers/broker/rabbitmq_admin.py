"""A small client for RabbitMQ's management HTTP API (users, permissions, connections).

Provisioning talks to whichever node answers: settings.RABBITMQ_API_URLS lists every
node's API (`http://user:password@host:port/api`), and a request that cannot reach a node
(refused, timed out, or a 5xx while it boots or stops) is retried on the next one. Users
and permissions are cluster-wide, so any node will do; the last node that answered is
tried first next time.

Only urllib: the API is a handful of JSON calls, not worth another dependency.
"""

from __future__ import annotations

import base64
import hashlib
import json
import logging
import secrets
import urllib.error
import urllib.request
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any
from urllib.parse import quote, unquote, urlsplit

log = logging.getLogger(__name__)

_DIRECT = urllib.request.build_opener(urllib.request.ProxyHandler({}))

# RabbitMQ's default hashing (rabbit_password_hashing_sha256): base64(salt ++ sha256(salt
# ++ password)) with a 4-byte salt. We compute it ourselves so the database can hold it
# and a replaced cluster can be rebuilt without knowing any password.
HASHING_ALGORITHM = "rabbit_password_hashing_sha256"
DEFAULT_VHOST = "/"


class RabbitMQAdminError(RuntimeError):
    """The API refused a request (4xx), or no node answered."""

    def __init__(self, message: str, status: int | None = None) -> None:
        super().__init__(message)
        self.status = status


def rabbit_password_hash(password: str, *, salt: bytes | None = None) -> str:
    """The `password_hash` RabbitMQ stores for `password` with HASHING_ALGORITHM."""
    salt = salt if salt is not None else secrets.token_bytes(4)
    return base64.b64encode(salt + hashlib.sha256(salt + password.encode()).digest()).decode()


@dataclass(frozen=True)
class Node:
    """One node's management API: where, and the credentials its URL carried."""

    base: str  # http://host:port/api, without credentials
    authorization: str

    @property
    def address(self) -> str:
        """`host:port`, as the operations page names a node."""
        return urlsplit(self.base).netloc

    @classmethod
    def parse(cls, url: str) -> Node:
        parts = urlsplit(url)
        if parts.scheme not in ("http", "https") or not parts.hostname:
            raise ValueError(f"not a management API URL: {url!r}")
        user, password = unquote(parts.username or ""), unquote(parts.password or "")
        token = base64.b64encode(f"{user}:{password}".encode()).decode()
        netloc = parts.hostname + (f":{parts.port}" if parts.port else "")
        return cls(f"{parts.scheme}://{netloc}{parts.path.rstrip('/')}", f"Basic {token}")


class RabbitMQAdmin:
    """The management API of a cluster, reached through any of its nodes."""

    def __init__(self, api_urls: Sequence[str], *, timeout: float = 10.0) -> None:
        if not api_urls:
            raise ValueError("no RabbitMQ management API URL (settings.RABBITMQ_API_URLS)")
        self.nodes = [Node.parse(url) for url in api_urls]
        self.timeout = timeout
        self._preferred = 0

    @classmethod
    def from_settings(cls) -> RabbitMQAdmin:
        from django.conf import settings

        return cls(settings.RABBITMQ_API_URLS)

    # -- transport ------------------------------------------------------------------------

    def request(self, method: str, path: str, body: object | None = None) -> Any:
        """JSON in, JSON out (None for an empty answer); the next node when one is down."""
        data = None if body is None else json.dumps(body).encode()
        failures: list[str] = []
        order = list(range(self._preferred, len(self.nodes))) + list(range(self._preferred))
        for index in order:
            node = self.nodes[index]
            try:
                answer = self.send(node, method, path, data)
            except urllib.error.HTTPError as exc:
                detail = _error_detail(exc)
                if exc.code >= 500:
                    failures.append(f"{node.base}: {exc.code} {detail}")
                    continue
                raise RabbitMQAdminError(
                    f"{method} {path}: {exc.code} {detail}", status=exc.code
                ) from None
            except OSError as exc:  # refused, unreachable, timed out (URLError too)
                failures.append(f"{node.base}: {getattr(exc, 'reason', exc)}")
                continue
            self._preferred = index
            return answer
        raise RabbitMQAdminError(
            f"no RabbitMQ node answered {method} {path}: {'; '.join(failures)}"
        )

    def send(self, node: Node, method: str, path: str, data: bytes | None = None) -> Any:
        """One request to one node; raises what urllib raises (HTTPError, OSError).
        Proxies are bypassed: the management API is the cluster's own, never behind one."""
        request = urllib.request.Request(
            f"{node.base}/{path.lstrip('/')}",
            method=method,
            data=data,
            headers={
                "content-type": "application/json",
                "accept": "application/json",
                "authorization": node.authorization,
            },
        )
        with _DIRECT.open(request, timeout=self.timeout) as response:
            raw = response.read()
        return json.loads(raw) if raw else None

    def delete(self, path: str) -> bool:
        """DELETE `path`; False if there was nothing to delete (the API answers 404)."""
        try:
            self.request("DELETE", path)
        except RabbitMQAdminError as exc:
            if exc.status == 404:
                return False
            raise
        return True

    # -- users and permissions ------------------------------------------------------------

    def users(self) -> list[dict[str, Any]]:
        return self.request("GET", "users")

    def put_user(self, name: str, password_hash: str, tags: Iterable[str] = ()) -> None:
        self.request(
            "PUT",
            f"users/{_q(name)}",
            {
                "password_hash": password_hash,
                "hashing_algorithm": HASHING_ALGORITHM,
                "tags": ",".join(tags),
            },
        )

    def delete_users(self, names: Sequence[str]) -> None:
        """Several users in one call (missing ones are ignored by RabbitMQ)."""
        if names:
            self.request("POST", "users/bulk-delete", {"users": list(names)})

    def import_definitions(self, definitions: dict[str, Any]) -> None:
        """Merge users, permissions, topic permissions... in one call (nothing is removed)."""
        self.request("POST", "definitions", definitions)

    # -- global parameters ----------------------------------------------------------------

    def global_parameters(self, prefix: str) -> list[str]:
        """The names after `prefix` of the cluster's global parameters that start with it."""
        listed = self.request("GET", "global-parameters") or []
        names = [p.get("name", "") for p in listed]
        return [name[len(prefix) :] for name in names if name.startswith(prefix)]

    def delete_global_parameter(self, name: str) -> bool:
        return self.delete(f"global-parameters/{_q(name)}")

    # -- connections and queues -----------------------------------------------------------

    def connections_of(self, users: Iterable[str]) -> list[str]:
        """Names of the open connections (on any node) authenticated as one of `users`."""
        wanted = set(users)
        if not wanted:
            return []
        listed = self.request("GET", "connections?columns=name,user") or []
        return [c["name"] for c in listed if c.get("user") in wanted]

    def close_connection(self, name: str, reason: str) -> bool:
        """True if it was open."""
        if not self.delete(f"connections/{_q(name)}"):
            return False
        log.info("closed RabbitMQ connection %s: %s", name, reason)
        return True

    def queues_named(self, pattern: str, vhost: str = DEFAULT_VHOST) -> list[str]:
        """Queue names matching a regular expression (the API filters them server-side)."""
        query = f"queues/{_q(vhost)}?columns=name&use_regex=true&page=1&page_size=500&name={_q(pattern)}"
        page = self.request("GET", query) or {}
        return [q["name"] for q in page.get("items", [])]

    def delete_queue(self, name: str, vhost: str = DEFAULT_VHOST) -> bool:
        return self.delete(f"queues/{_q(vhost)}/{_q(name)}")


def _q(segment: str) -> str:
    return quote(segment, safe="")


def _error_detail(exc: urllib.error.HTTPError) -> str:
    try:
        body = json.loads(exc.read() or b"{}")
    except ValueError:
        return exc.reason or ""
    return str(body.get("reason") or body.get("error") or exc.reason or "")
