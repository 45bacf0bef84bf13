"""What the operations page shows: every process instance and the figures worth watching.

`gather()` reads each source once, in parallel, with short timeouts: the instance hashes
and process totals in Redis (workers.counters), the Redis outbox and Celery queue, the
Celery workers (a broadcast ping), and the broker (Mosquitto's `$SYS/broker/#` topics, or
RabbitMQ's management API on every node). Every source answers with `at` (when it was
read) and either its figures or `available: False` with the reason: an unreachable source
is never shown as zero. `watch` then rates the figures that say the platform is falling
behind (thresholds in docs/scaling.md).
"""

from __future__ import annotations

import base64
import json
import logging
import threading
import time
import urllib.error
import urllib.request
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import Any
from urllib.parse import unquote, urlsplit

import paho.mqtt.client as mqtt
import redis
from django.conf import settings

from telemetry.status import ingest_status
from workers import counters
from workers.broker import mosquitto_sys
from workers.broker.mosquitto_sys import MOSQUITTO_SYS

log = logging.getLogger(__name__)

# The processes a deployment runs; each is listed even when nothing of it reports.
PROCESSES = ("web", "gateway", "ingest", "pastview", "celery")

LAG_LIMIT_S = 1.0  # sustained ingest must keep its lag under 1 s
QUEUE_DEPTH_LIMIT = 10_000  # messages waiting anywhere: more is "falling behind" at once
TREND_WINDOW_S = 60.0  # "rising" and "growing" compare with the oldest sample this recent
TREND_MIN_AGE_S = 3.0  # ...that is at least this old, so two quick reloads do not compare
GONE_WARN_S = 600  # an instance gone this recently is worth a look; older ones are history

HISTORY_KEY = "skyhive:operations:history"
CELERY_SEEN_KEY = "skyhive:operations:celery"
OUTBOX_PATTERN = "skyhive:gateway:outbox:*"

CELERY_PING_TIMEOUT_S = 0.5
SYS_WAIT_S = 1.5
SYS_GRACE_S = 0.3
HTTP_TIMEOUT_S = 2.0


def may_see(user: Any) -> bool:
    """Operators and admins (of any of their organisations) and staff see the operations
    figures; viewers do not: host names, pids and queue depths are the platform's, not
    their organisation's."""
    from fleet.models import Membership, Role

    if not getattr(user, "is_authenticated", False):
        return False
    if user.is_staff:
        return True
    return Membership.objects.filter(user=user, role__in=[Role.OPERATOR, Role.ADMIN]).exists()


def _unavailable(error: object) -> dict[str, Any]:
    text = str(error).splitlines()[0] if str(error) else type(error).__name__
    return {"available": False, "error": text, "at": time.time()}


def _guarded(source: Callable[[], dict[str, Any]]) -> dict[str, Any]:
    """Run one source; any failure becomes `available: False`, never an exception."""
    try:
        return source()
    except Exception as exc:  # noqa: BLE001 - one broken source must not hide the others
        log.warning("operations source %s failed: %s", source.__name__, exc)
        return _unavailable(exc)


# -- Redis: instances, process totals, queues -----------------------------------------------


def instance_figures() -> dict[str, Any]:
    """Instances grouped by process, with how many are alive."""
    found = counters.instances()
    by_process: dict[str, list[dict]] = {name: [] for name in PROCESSES if name != "celery"}
    for instance in found:
        by_process.setdefault(instance.process, []).append(instance.as_dict())
    return {
        "available": True,
        "at": time.time(),
        "processes": {
            name: {
                "alive": sum(1 for i in items if i["alive"]),
                "gone": sum(1 for i in items if not i["alive"]),
                "instances": items,
            }
            for name, items in by_process.items()
        },
    }


def gateway_figures() -> dict[str, Any]:
    """Received / handled / dropped by reason, over every gateway since Redis started."""
    totals = counters.snapshot().get("gateway", {})
    dropped = {
        name.split(".", 1)[1]: int(value)
        for name, value in sorted(totals.items())
        if name.startswith("dropped.")
    }
    return {
        "available": True,
        "at": time.time(),
        "received": int(totals.get("received", 0)),
        "handled": int(totals.get("handled", 0)),
        "published": int(totals.get("published", 0)),
        "dropped": dropped,
        "dropped_total": int(totals.get("dropped", sum(dropped.values()))),
        "updated_at": totals.get("updated_at"),
    }


def ingest_figures() -> dict[str, Any]:
    status = ingest_status()
    if not status.get("available"):
        return _unavailable(status.get("error", "unavailable"))
    return {**status, "at": time.time()}


def _celery_queue_names() -> list[str]:
    names = [getattr(settings, "CELERY_TASK_DEFAULT_QUEUE", "celery")]
    logs_queue = getattr(settings, "LOGS_IMPORT_QUEUE", None)
    if logs_queue and logs_queue not in names:
        names.append(logs_queue)
    return names


def queue_figures() -> dict[str, Any]:
    """The gateways' outbox (commands waiting for a gateway) and Celery's queue(s)."""
    client = counters._client()
    outboxes = {key: int(client.llen(key)) for key in client.scan_iter(OUTBOX_PATTERN)}
    out: dict[str, Any] = {
        "available": True,
        "at": time.time(),
        "outbox": sum(outboxes.values()),
        "outboxes": {
            key.rsplit(":", 2)[-2] + ":" + key.rsplit(":", 1)[-1]: n for key, n in outboxes.items()
        },
    }
    broker_url = settings.CELERY_BROKER_URL
    if broker_url.startswith(("redis://", "rediss://")):
        celery_redis = redis.Redis.from_url(broker_url, socket_timeout=1)
        queues = {name: int(celery_redis.llen(name)) for name in _celery_queue_names()}
        out["celery_queues"] = queues
        out["celery_queue"] = sum(queues.values())
        # Kombu's Redis transport keeps tasks taken but not yet acknowledged here.
        out["celery_unacked"] = int(celery_redis.hlen("unacked"))
    else:
        out["celery_queue"] = None
        out["celery_error"] = "the Celery broker is not Redis; see its own monitoring"
    return out


def celery_figures() -> dict[str, Any]:
    """Workers answering a broadcast ping now, and those seen within the last hour."""
    from config.celery import app

    replies = app.control.ping(timeout=CELERY_PING_TIMEOUT_S) or []
    now = time.time()
    alive = sorted(name for reply in replies for name in reply)
    client = counters._client()
    if alive:
        client.hset(CELERY_SEEN_KEY, mapping={name: now for name in alive})
    seen = {name: float(at) for name, at in client.hgetall(CELERY_SEEN_KEY).items()}
    forget = [name for name, at in seen.items() if now - at > counters.GONE_RETAIN_S]
    if forget:
        client.hdel(CELERY_SEEN_KEY, *forget)
    workers = [
        {
            "process": "celery",
            "instance": name,
            "host": name.split("@", 1)[-1],
            "alive": name in alive,
            "last_report": seen[name],
        }
        for name in sorted(seen)
        if name not in forget
    ]
    return {
        "available": True,
        "at": now,
        "alive": len(alive),
        "gone": sum(1 for w in workers if not w["alive"]),
        "instances": workers,
    }


# -- the broker ------------------------------------------------------------------------------


def mosquitto_figures(url: str | None = None, wait: float = SYS_WAIT_S) -> dict[str, Any]:
    """Subscribe briefly to `$SYS/broker/#` as the ground user; Mosquitto retains them."""
    parts = urlsplit(url or settings.MQTT_URL)
    got: dict[str, str] = {}
    state: dict[str, Any] = {}
    done = threading.Event()

    def on_connect(client, userdata, flags, reason_code, properties) -> None:  # type: ignore[no-untyped-def]
        state["rc"] = reason_code
        if reason_code.is_failure:
            done.set()
            return
        client.subscribe("$SYS/broker/#", qos=0)

    def on_message(client, userdata, message) -> None:  # type: ignore[no-untyped-def]
        name = mosquitto_sys.figure_name(message.topic)
        if name:
            got[name] = message.payload.decode(errors="replace")
            if len(got) == len(MOSQUITTO_SYS):
                done.set()

    def on_subscribe(client, userdata, mid, reason_codes, properties) -> None:  # type: ignore[no-untyped-def]
        state["subscribed"] = time.monotonic()

    client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id="", clean_session=True)
    client.on_subscribe = on_subscribe
    if parts.username:
        client.username_pw_set(unquote(parts.username), unquote(parts.password or ""))
    client.on_connect = on_connect
    client.on_message = on_message
    host, port = parts.hostname or "127.0.0.1", parts.port or 1883
    try:
        client.connect(host, port, keepalive=5)
    except OSError as exc:
        return {
            **_unavailable(exc),
            "kind": "mosquitto",
            "address": f"{host}:{port}",
            "endpoints": [{"address": f"{host}:{port}", "up": False, "error": str(exc)}],
            "nodes_up": 0,
            "nodes_down": 1,
        }
    client.loop_start()
    deadline = time.monotonic() + wait
    try:
        # Retained $SYS messages follow the SUBACK at once; a short grace after it is
        # enough, and spares the full wait when the ACL hides $SYS.
        while not done.wait(0.05) and time.monotonic() < deadline:
            subscribed = state.get("subscribed")
            if subscribed and time.monotonic() - subscribed > SYS_GRACE_S:
                break
    finally:
        client.disconnect()
        client.loop_stop()
    base = {"kind": "mosquitto", "address": f"{host}:{port}", "at": time.time()}
    rc = state.get("rc")
    if rc is None:
        return {**base, "available": False, "error": "no answer to CONNECT"}
    if rc.is_failure:
        return {**base, "available": False, "error": f"refused: {rc}"}
    if not got:
        return {
            **base,
            "nodes_up": 1,
            "nodes_down": 0,
            "available": False,
            "error": "no $SYS figures: the ground user may not read $SYS/# (broker ACL)",
        }
    # Counts unchanged for a minute have expired from $SYS; the gateways saw them last.
    try:
        held = mosquitto_sys.remembered(counters._client())
    except redis.RedisError:
        held = {}
    figures, from_gateways = mosquitto_sys.fill_in(got, held)
    return {
        **base,
        "available": True,
        "nodes_up": 1,
        "nodes_down": 0,
        "from_gateways": from_gateways,
        **figures,
    }


def _http_json(api_url: str, path: str) -> Any:
    """GET one management API path with the URL's own credentials; proxies bypassed."""
    parts = urlsplit(api_url)
    auth = base64.b64encode(
        f"{unquote(parts.username or '')}:{unquote(parts.password or '')}".encode()
    ).decode()
    request = urllib.request.Request(
        f"{parts.scheme}://{parts.hostname}:{parts.port}{parts.path.rstrip('/')}/{path}",
        headers={"authorization": f"Basic {auth}", "accept": "application/json"},
    )
    opener = urllib.request.build_opener(urllib.request.ProxyHandler({}))
    with opener.open(request, timeout=HTTP_TIMEOUT_S) as response:
        return json.loads(response.read())


def _address(api_url: str) -> str:
    parts = urlsplit(api_url)
    return f"{parts.hostname}:{parts.port}"


def rabbitmq_figures(api_urls: list[str] | None = None) -> dict[str, Any]:
    """Nodes up and down, our queues' depths, connections, from any node that answers.

    A node is down when its own management API does not answer, or when a node that does
    answer says it is not running: either way it is named.
    """
    urls = list(api_urls if api_urls is not None else settings.RABBITMQ_API_URLS)
    now = time.time()
    if not urls:
        return {**_unavailable("RABBITMQ_API_URLS is empty"), "kind": "rabbitmq"}
    endpoints = []
    answering: str | None = None
    for url in urls:
        try:
            overview = _http_json(url, "overview")
        except urllib.error.HTTPError as exc:
            # The node answers but refuses us (credentials, permissions): up, unreadable.
            endpoints.append(
                {"address": _address(url), "up": True, "error": f"HTTP {exc.code} {exc.reason}"}
            )
            continue
        except (OSError, ValueError) as exc:
            reason = getattr(exc, "reason", exc)
            endpoints.append({"address": _address(url), "up": False, "error": str(reason)})
            continue
        endpoints.append({"address": _address(url), "up": True, "node": overview.get("node")})
        answering = answering or url
    if answering is None:
        refused = [e["error"] for e in endpoints if e["up"]]
        return {
            "kind": "rabbitmq",
            "available": False,
            "error": (
                f"the management API refuses us: {refused[0]}"
                if refused
                else "no node's management API answers"
            ),
            "at": now,
            "endpoints": endpoints,
            "nodes_up": len(refused),
            "nodes_down": len(urls) - len(refused),
        }
    overview = _http_json(answering, "overview")
    nodes = _http_json(answering, "nodes?columns=name,running,mem_used,fd_used,sockets_used")
    queues = _http_json(
        answering,
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
    ours = [q for q in queues if q["name"].startswith("skyhive.")]
    sessions = [q for q in queues if q["name"].startswith("mqtt-subscription-")]
    totals = overview.get("object_totals", {})
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
        "connections": totals.get("connections"),
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


def broker_figures() -> dict[str, Any]:
    if settings.MQTT_BROKER == "rabbitmq":
        return rabbitmq_figures()
    return mosquitto_figures()


# -- what to watch ---------------------------------------------------------------------------


def broker_queue_depth(broker: dict[str, Any]) -> int | None:
    """Messages waiting in the broker for a ground process or a drone."""
    if not broker.get("available"):
        return None
    if broker.get("kind") == "rabbitmq":
        ours = sum(q["ready"] + q["unacked"] for q in broker["queues"])
        sessions = broker["mqtt_sessions"]
        return ours + sessions["ready"] + sessions["unacked"]
    stored = broker.get("store_messages", broker.get("messages_stored"))
    return stored if isinstance(stored, int) else None


def _history(sample: dict[str, Any]) -> dict[str, Any] | None:
    """Store this sample; return the oldest one of the trend window (None if too young)."""
    client = counters._client()
    now = sample["at"]
    pipe = client.pipeline(transaction=False)
    pipe.zadd(HISTORY_KEY, {json.dumps(sample, sort_keys=True): now})
    pipe.zremrangebyscore(HISTORY_KEY, "-inf", now - TREND_WINDOW_S)
    pipe.zrangebyscore(HISTORY_KEY, now - TREND_WINDOW_S, now - TREND_MIN_AGE_S, start=0, num=1)
    pipe.expire(HISTORY_KEY, int(TREND_WINDOW_S * 2))
    oldest = pipe.execute()[2]
    return json.loads(oldest[0]) if oldest else None


def _item(
    key: str,
    label: str,
    value: Any,
    state: str,
    at: float | None,
    rule: str,
    unit: str = "",
    detail: str = "",
) -> dict[str, Any]:
    return {
        "key": key,
        "label": label,
        "value": value,
        "unit": unit,
        "state": state,
        "at": at,
        "rule": rule,
        "detail": detail,
    }


def _rising(key: str, now_value: Any, old: dict[str, Any] | None) -> bool:
    before = (old or {}).get(key)
    return (
        isinstance(now_value, int | float)
        and isinstance(before, int | float)
        and (now_value > before)
    )


def watch(figures: dict[str, Any]) -> list[dict[str, Any]]:
    """The figures to watch with a state each: ok, warn, bad, or unknown (not readable)."""
    ingest, gateway = figures["ingest"], figures["gateway"]
    queues, broker, procs = figures["queues"], figures["broker"], figures["instances"]
    sample = {
        "at": figures["generated_at"],
        "gateway_dropped": gateway.get("dropped_total") if gateway.get("available") else None,
        "ingest_dropped": ingest.get("dropped_total") if ingest.get("available") else None,
        "broker_depth": broker_queue_depth(broker),
        "outbox": queues.get("outbox") if queues.get("available") else None,
        "celery_queue": queues.get("celery_queue") if queues.get("available") else None,
    }
    try:
        old = _history(sample)
    except redis.RedisError:
        old = None
    items = []

    lag = ingest.get("lag_s") if ingest.get("available") else None
    if lag is None:
        state = "unknown"
    else:
        state = "bad" if lag > LAG_LIMIT_S else "ok"
    no_ingest = ingest.get("available") and not ingest.get("instances_alive")
    items.append(
        _item(
            "ingest_lag",
            "Ingest lag",
            lag,
            state,
            ingest.get("at"),
            f"bad above {LAG_LIMIT_S:g} s",
            unit="s",
            detail="no ingest instance alive" if no_ingest else "",
        )
    )

    for key, label, source in (
        ("gateway_dropped", "Gateway drops", gateway),
        ("ingest_dropped", "Ingest drops", ingest),
    ):
        value = sample[key]
        if value is None:
            state = "unknown"
        else:
            state = "warn" if _rising(key, value, old) else "ok"
        detail = f"+{value - old[key]} in the last minute" if state == "warn" and old else ""
        items.append(
            _item(key, label, value, state, source.get("at"), "warn while rising", detail=detail)
        )

    for key, label, source in (
        ("broker_depth", "Broker queue depth", broker),
        ("outbox", "Command outbox", queues),
        ("celery_queue", "Celery queue", queues),
    ):
        value = sample[key]
        if value is None:
            state = "unknown"
        elif value > QUEUE_DEPTH_LIMIT:
            state = "bad"
        else:
            state = "warn" if _rising(key, value, old) else "ok"
        items.append(
            _item(
                key,
                label,
                value,
                state,
                source.get("at"),
                f"warn while growing, bad above {QUEUE_DEPTH_LIMIT}",
            )
        )

    if "nodes_down" in broker:
        down = broker["nodes_down"]
        state = "bad" if down else "ok"
        names = [e["address"] for e in broker.get("endpoints", []) if not e["up"]]
        names += [n["name"] for n in broker.get("nodes", []) if not n["running"]]
        items.append(
            _item(
                "broker_nodes_down",
                "Broker nodes down",
                down,
                state,
                broker.get("at"),
                "bad when any node is down",
                detail=", ".join(dict.fromkeys(names)),
            )
        )
    else:
        items.append(
            _item(
                "broker_nodes_down",
                "Broker nodes down",
                None,
                "unknown",
                broker.get("at"),
                "bad when any node is down",
                detail=broker.get("error", ""),
            )
        )

    for process in ("gateway", "ingest"):
        group = procs.get("processes", {}).get(process) if procs.get("available") else None
        if group is None:
            items.append(
                _item(
                    f"{process}_instances",
                    f"{process.title()} instances alive",
                    None,
                    "unknown",
                    procs.get("at"),
                    "bad when none is alive",
                )
            )
            continue
        alive = group["alive"]
        recent = figures["generated_at"] - GONE_WARN_S
        gone = sum(1 for i in group["instances"] if not i["alive"] and i["last_report"] > recent)
        state = "bad" if alive == 0 else ("warn" if gone else "ok")
        items.append(
            _item(
                f"{process}_instances",
                f"{process.title()} instances alive",
                alive,
                state,
                procs.get("at"),
                f"bad when none is alive, warn when one went in the last {GONE_WARN_S // 60} min",
                detail=f"{gone} gone lately" if gone else "",
            )
        )
    sources = {
        "ingest_lag": ingest,
        "gateway_dropped": gateway,
        "ingest_dropped": ingest,
        "broker_depth": broker,
        "outbox": queues,
        "celery_queue": queues,
        "gateway_instances": procs,
        "ingest_instances": procs,
    }
    for item in items:
        source = sources.get(item["key"])
        # Unreadable (the page says "unreachable") versus read but without a value.
        item["readable"] = (
            "nodes_down" in broker if source is None else bool(source.get("available"))
        )
    return items


def gather() -> dict[str, Any]:
    """Every figure of the operations page, read now, each source independently."""
    sources: dict[str, Callable[[], dict[str, Any]]] = {
        "instances": instance_figures,
        "celery": celery_figures,
        "gateway": gateway_figures,
        "ingest": ingest_figures,
        "queues": queue_figures,
        "broker": broker_figures,
    }
    with ThreadPoolExecutor(max_workers=len(sources), thread_name_prefix="operations") as pool:
        futures = {name: pool.submit(_guarded, source) for name, source in sources.items()}
        figures: dict[str, Any] = {name: future.result() for name, future in futures.items()}
    celery = figures["celery"]
    if figures["instances"].get("available") and celery.get("available"):
        figures["instances"]["processes"]["celery"] = {
            key: celery[key] for key in ("alive", "gone", "instances")
        }
    figures["generated_at"] = time.time()
    figures["broker_kind"] = settings.MQTT_BROKER
    figures["watch"] = watch(figures)
    return figures
