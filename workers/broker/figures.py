"""The broker's figures for the operations page: written by the gateways, read by the page.

The page never talks to the broker itself. On Mosquitto each gateway keeps what it sees of
`$SYS/broker/#` and of its own link in Redis (workers.broker.mosquitto_sys); on RabbitMQ
each gateway polls the management API of every node every few seconds (`RabbitMQPoller`,
off the MQTT thread) and stores the result. `read_figures` turns either into the page's
broker figures. Every answer has `at` (when it was read) and either figures or
`available: False` with the reason: an unreadable broker is never shown as zero.
"""

from __future__ import annotations

import json
import logging
import threading
import time
import urllib.error
from typing import Any

import redis

from . import mosquitto_sys
from .rabbitmq_admin import Node, RabbitMQAdmin

log = logging.getLogger(__name__)

RABBITMQ_KEY = "skyhive:broker-figures:rabbitmq"
POLL_EVERY_S = 5.0
# A poll older than this is stale (its gateways are gone): the page says so.
RABBITMQ_TTL_S = 4 * POLL_EVERY_S
HTTP_TIMEOUT_S = 2.0


def unavailable(error: object, **extra: Any) -> dict[str, Any]:
    text = str(error).splitlines()[0] if str(error) else type(error).__name__
    return {"available": False, "error": text, "at": time.time(), **extra}


def read_figures(client: redis.Redis, kind: str, mosquitto_address: str) -> dict[str, Any]:
    """The broker figures the gateways last wrote, for the broker of kind `kind`."""
    if kind == "rabbitmq":
        raw = client.get(RABBITMQ_KEY)
        if raw is None:
            return unavailable("no gateway has polled RabbitMQ lately", kind="rabbitmq")
        return json.loads(raw)
    return mosquitto_figures(mosquitto_sys.views(client), mosquitto_address)


# -- Mosquitto ---------------------------------------------------------------------------------


def mosquitto_figures(views: list[dict[str, str]], address: str) -> dict[str, Any]:
    """The node is up when a gateway's link to it is; its figures are the freshest of those
    the gateways hold (Mosquitto's counts expire from $SYS a minute after they change)."""
    base = {"kind": "mosquitto", "address": address}
    mine = [view for view in views if view.get(mosquitto_sys.ADDRESS) == address]
    if not mine:
        return unavailable(f"no gateway reports on the broker at {address}", **base)
    up = [view for view in mine if view.get(mosquitto_sys.LINK) == "up"]
    if not up:
        return _node_down(mine, base)
    figures = mosquitto_sys.merged(up)
    at = max(float(view.get("at", 0)) for view in up)
    node = {"nodes_up": 1, "nodes_down": 0, "endpoints": [{"address": address, "up": True}]}
    if not figures:
        error = "no $SYS figures: the ground user may not read $SYS/# (broker ACL)"
        return {**unavailable(error, **base, **node), "at": at}
    return {**base, **node, "available": True, "at": at, **figures}


def _node_down(views: list[dict[str, str]], base: dict[str, Any]) -> dict[str, Any]:
    latest = max(views, key=lambda view: float(view.get("at", 0)))
    error = latest.get(mosquitto_sys.ERROR) or "no gateway is connected to it"
    endpoint = {"address": base["address"], "up": False, "error": error}
    down = {"nodes_up": 0, "nodes_down": 1, "endpoints": [endpoint]}
    return {**unavailable(error, **base, **down), "at": float(latest.get("at", 0))}


# -- RabbitMQ ----------------------------------------------------------------------------------


def rabbitmq_figures(api_urls: list[str]) -> dict[str, Any]:
    """Nodes up and down, our queues' depths, connections, from any node that answers.

    A node is down when its own management API does not answer, or when a node that does
    answer says it is not running: either way it is named.
    """
    if not api_urls:
        return unavailable("RABBITMQ_API_URLS is empty", kind="rabbitmq")
    admin = RabbitMQAdmin(api_urls, timeout=HTTP_TIMEOUT_S)
    endpoints, answering = _probe_nodes(admin)
    if answering is None:
        return _no_node_answers(endpoints)
    return _cluster_figures(admin, answering, endpoints)


def _probe_nodes(admin: RabbitMQAdmin) -> tuple[list[dict[str, Any]], Node | None]:
    """Ask every node for its overview: which answer, and the first that does."""
    endpoints: list[dict[str, Any]] = []
    answering: Node | None = None
    for node in admin.nodes:
        try:
            overview = admin.send(node, "GET", "overview")
        except urllib.error.HTTPError as exc:
            # The node answers but refuses us (credentials, permissions): up, unreadable.
            error = f"HTTP {exc.code} {exc.reason}"
            endpoints.append({"address": node.address, "up": True, "error": error})
            continue
        except (OSError, ValueError) as exc:
            reason = getattr(exc, "reason", exc)
            endpoints.append({"address": node.address, "up": False, "error": str(reason)})
            continue
        endpoints.append({"address": node.address, "up": True, "node": overview.get("node")})
        answering = answering or node
    return endpoints, answering


def _no_node_answers(endpoints: list[dict[str, Any]]) -> dict[str, Any]:
    refused = [e["error"] for e in endpoints if e["up"]]
    error = (
        f"the management API refuses us: {refused[0]}"
        if refused
        else "no node's management API answers"
    )
    return unavailable(
        error,
        kind="rabbitmq",
        endpoints=endpoints,
        nodes_up=len(refused),
        nodes_down=len(endpoints) - len(refused),
    )


def _cluster_figures(
    admin: RabbitMQAdmin, node: Node, endpoints: list[dict[str, Any]]
) -> dict[str, Any]:
    overview = admin.send(node, "GET", "overview")
    nodes = admin.send(node, "GET", "nodes?columns=name,running,mem_used,fd_used,sockets_used")
    queues = admin.send(
        node,
        "GET",
        "queues?columns=name,messages_ready,messages_unacknowledged,consumers,node,state",
    )
    node_rows = [
        {
            "name": n["name"],
            "running": bool(n.get("running")),
            "mem_used": n.get("mem_used"),
            "sockets_used": n.get("sockets_used"),
        }
        for n in nodes
    ]
    # An endpoint that does not answer while the cluster still lists its node as running
    # (the node is alive, its API is not) still counts as down: the ground cannot see it.
    down_names = {n["name"] for n in node_rows if not n["running"]}
    unanswered = sum(1 for e in endpoints if not e["up"])
    return {
        "kind": "rabbitmq",
        "available": True,
        "at": time.time(),
        "cluster": overview.get("cluster_name"),
        "version": overview.get("rabbitmq_version"),
        "endpoints": endpoints,
        "nodes": node_rows,
        "nodes_up": sum(1 for n in node_rows if n["running"]),
        "nodes_down": max(len(down_names), unanswered),
        "connections": overview.get("object_totals", {}).get("connections"),
        **_queue_figures(queues),
    }


def _queue_figures(queues: list[dict[str, Any]]) -> dict[str, Any]:
    """Our own queues one by one; the MQTT plugin's session queues summed up."""
    ours = [q for q in queues if q["name"].startswith("skyhive.")]
    sessions = [q for q in queues if q["name"].startswith("mqtt-subscription-")]
    return {
        "queues": [
            {
                "name": q["name"],
                "ready": q.get("messages_ready", 0),
                "unacked": q.get("messages_unacknowledged", 0),
                "consumers": q.get("consumers", 0),
                "node": q.get("node"),
            }
            for q in sorted(ours, key=lambda q: q["name"])
        ],
        "mqtt_sessions": {
            "queues": len(sessions),
            "ready": sum(q.get("messages_ready", 0) for q in sessions),
            "unacked": sum(q.get("messages_unacknowledged", 0) for q in sessions),
        },
    }


def publish_rabbitmq_figures(client: redis.Redis, api_urls: list[str]) -> dict[str, Any]:
    """Poll the cluster once and store what it said (or why it said nothing)."""
    try:
        figures = rabbitmq_figures(api_urls)
    except Exception as exc:  # noqa: BLE001 - a broken answer is shown, not raised
        figures = unavailable(exc, kind="rabbitmq")
    client.set(RABBITMQ_KEY, json.dumps(figures), ex=int(RABBITMQ_TTL_S))
    return figures


class RabbitMQPoller:
    """A gateway's thread storing the cluster's figures every POLL_EVERY_S. Several
    gateways each poll: the latest write wins, and the figures outlive any one of them."""

    def __init__(self, client: redis.Redis, api_urls: list[str]) -> None:
        self.client = client
        self.api_urls = list(api_urls)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="rabbitmq-figures", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def stop(self, timeout: float = 5.0) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout)

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                publish_rabbitmq_figures(self.client, self.api_urls)
            except redis.RedisError as exc:
                log.warning("broker figures not stored: %s", exc)
            self._stop.wait(POLL_EVERY_S)
