"""What the operations page shows: every process instance and the figures worth watching.

`gather()` reads each source once, in parallel, with short timeouts: the instance hashes
and process totals in Redis (workers.counters), the Redis outbox and Celery queue, the
Celery workers (a broadcast ping), and the broker figures the gateways keep in Redis
(workers.broker.figures: Mosquitto's `$SYS/broker/#` topics, or RabbitMQ's management API
polled every few seconds); the page itself never connects to the broker. Every source
answers with `at` (when it was read) and either its figures or `available: False` with the
reason: an unreachable source is never shown as zero. `watch` then rates the figures that
say the platform is falling behind (thresholds in docs/scaling.md).
"""

from __future__ import annotations

import json
import logging
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import redis
from celery import current_app
from django.conf import settings

from onboard.mqtt import parse_broker_url
from workers import counters
from workers.broker import figures as broker_figures
from workers.broker.figures import unavailable
from workers.ingest_status import ingest_status

log = logging.getLogger(__name__)

# The processes a deployment runs; each is listed even when nothing of it reports.
PROCESSES = ("web", "gateway", "ingest", "pastview", "celery")

LAG_LIMIT_S = 1.0  # sustained ingest keeps its lag under a second (docs/scaling.md)
QUEUE_DEPTH_LIMIT = 10_000  # messages waiting anywhere: more is "falling behind" at once
TREND_WINDOW_S = 60.0  # "rising" and "growing" compare with the oldest sample this recent
TREND_MIN_AGE_S = 3.0  # ...that is at least this old, so two quick reloads do not compare
GONE_WARN_S = 600  # an instance gone this recently is worth a look; older ones are history

HISTORY_KEY = "skyhive:operations:history"
CELERY_SEEN_KEY = "skyhive:operations:celery"
OUTBOX_PATTERN = "skyhive:gateway:outbox:*"

CELERY_PING_TIMEOUT_S = 0.5


def _guarded(source: Callable[[], dict[str, Any]]) -> dict[str, Any]:
    """Run one source; any failure becomes `available: False`, never an exception."""
    try:
        return source()
    except Exception as exc:  # noqa: BLE001 - one broken source must not hide the others
        log.warning("operations source %s failed: %s", source.__name__, exc)
        return unavailable(exc)


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
        return unavailable(status.get("error", "unavailable"))
    return {**status, "at": time.time()}


def _celery_queue_names() -> list[str]:
    names = [getattr(settings, "CELERY_TASK_DEFAULT_QUEUE", "celery")]
    for setting in ("SAFETY_TASK_QUEUE", "LOGS_IMPORT_QUEUE"):
        queue = getattr(settings, setting, None)
        if queue and queue not in names:
            names.append(queue)
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
    # The project's Celery app (config.celery), made current when config is imported.
    replies = current_app.control.ping(timeout=CELERY_PING_TIMEOUT_S) or []
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


def broker_figures_now() -> dict[str, Any]:
    """What the gateways last wrote about the configured broker."""
    node = parse_broker_url(settings.MQTT_URL)  # as the gateways name the node they are on
    address = f"{node.host}:{node.port}"
    return broker_figures.read_figures(counters._client(), settings.MQTT_BROKER, address)


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
    source: dict[str, Any],
    rule: str,
    unit: str = "",
    detail: str = "",
    readable: bool | None = None,
) -> dict[str, Any]:
    """One watched figure, read from `source`. `readable` (default: the source was read)
    tells "unreachable" from "read, without a value" on the page."""
    return {
        "key": key,
        "label": label,
        "value": value,
        "unit": unit,
        "state": state,
        "at": source.get("at"),
        "rule": rule,
        "detail": detail,
        "readable": bool(source.get("available")) if readable is None else readable,
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
    sample = _sample(figures)
    try:
        old = _history(sample)
    except redis.RedisError:
        old = None
    now = figures["generated_at"]
    return [
        _lag_item(ingest),
        _drops_item("gateway_dropped", "Gateway drops", gateway, sample, old),
        _drops_item("ingest_dropped", "Ingest drops", ingest, sample, old),
        _depth_item("broker_depth", "Broker queue depth", broker, sample, old),
        _depth_item("outbox", "Command outbox", queues, sample, old),
        _depth_item("celery_queue", "Celery queue", queues, sample, old),
        _nodes_down_item(broker),
        _instances_item("gateway", procs, now),
        _instances_item("ingest", procs, now),
    ]


def _sample(figures: dict[str, Any]) -> dict[str, Any]:
    """The figures whose trend is watched, None where their source was not read."""
    ingest, gateway, queues = figures["ingest"], figures["gateway"], figures["queues"]
    return {
        "at": figures["generated_at"],
        "gateway_dropped": gateway.get("dropped_total") if gateway.get("available") else None,
        "ingest_dropped": ingest.get("dropped_total") if ingest.get("available") else None,
        "broker_depth": broker_queue_depth(figures["broker"]),
        "outbox": queues.get("outbox") if queues.get("available") else None,
        "celery_queue": queues.get("celery_queue") if queues.get("available") else None,
    }


def _lag_item(ingest: dict[str, Any]) -> dict[str, Any]:
    """Ingest lag is bad above LAG_LIMIT_S."""
    lag = ingest.get("lag_s") if ingest.get("available") else None
    if lag is None:
        state = "unknown"
    else:
        state = "bad" if lag > LAG_LIMIT_S else "ok"
    no_ingest = ingest.get("available") and not ingest.get("instances_alive")
    return _item(
        "ingest_lag",
        "Ingest lag",
        lag,
        state,
        ingest,
        f"bad above {LAG_LIMIT_S:g} s",
        unit="s",
        detail="no ingest instance alive" if no_ingest else "",
    )


def _drops_item(
    key: str, label: str, source: dict[str, Any], sample: dict[str, Any], old: dict | None
) -> dict[str, Any]:
    """Drops are counted since Redis started: a warning while they rise, not for having any."""
    value = sample[key]
    if value is None:
        state = "unknown"
    else:
        state = "warn" if _rising(key, value, old) else "ok"
    detail = f"+{value - old[key]} in the last minute" if state == "warn" and old else ""
    return _item(key, label, value, state, source, "warn while rising", detail=detail)


def _depth_item(
    key: str, label: str, source: dict[str, Any], sample: dict[str, Any], old: dict | None
) -> dict[str, Any]:
    """A queue is bad above QUEUE_DEPTH_LIMIT, and worth a look while it grows."""
    value = sample[key]
    if value is None:
        state = "unknown"
    elif value > QUEUE_DEPTH_LIMIT:
        state = "bad"
    else:
        state = "warn" if _rising(key, value, old) else "ok"
    rule = f"warn while growing, bad above {QUEUE_DEPTH_LIMIT}"
    return _item(key, label, value, state, source, rule)


def _nodes_down_item(broker: dict[str, Any]) -> dict[str, Any]:
    """Any broker node down is bad, named in the detail; unknown when nobody could tell."""
    rule = "bad when any node is down"
    if "nodes_down" not in broker:
        detail = broker.get("error", "")
        return _item(
            "broker_nodes_down",
            "Broker nodes down",
            None,
            "unknown",
            broker,
            rule,
            detail=detail,
            readable=False,
        )
    down = broker["nodes_down"]
    names = [e["address"] for e in broker.get("endpoints", []) if not e["up"]]
    names += [n["name"] for n in broker.get("nodes", []) if not n["running"]]
    return _item(
        "broker_nodes_down",
        "Broker nodes down",
        down,
        "bad" if down else "ok",
        broker,
        rule,
        detail=", ".join(dict.fromkeys(names)),
        readable=True,
    )


def _instances_item(process: str, procs: dict[str, Any], now: float) -> dict[str, Any]:
    """Bad when no instance of `process` is alive; a warning when one went lately."""
    key, label = f"{process}_instances", f"{process.title()} instances alive"
    group = procs.get("processes", {}).get(process) if procs.get("available") else None
    if group is None:
        return _item(key, label, None, "unknown", procs, "bad when none is alive")
    alive = group["alive"]
    recent = now - GONE_WARN_S
    gone = sum(1 for i in group["instances"] if not i["alive"] and i["last_report"] > recent)
    state = "bad" if alive == 0 else ("warn" if gone else "ok")
    return _item(
        key,
        label,
        alive,
        state,
        procs,
        f"bad when none is alive, warn when one went in the last {GONE_WARN_S // 60} min",
        detail=f"{gone} gone lately" if gone else "",
    )


def gather() -> dict[str, Any]:
    """Every figure of the operations page, read now, each source independently."""
    sources: dict[str, Callable[[], dict[str, Any]]] = {
        "instances": instance_figures,
        "celery": celery_figures,
        "gateway": gateway_figures,
        "ingest": ingest_figures,
        "queues": queue_figures,
        "broker": broker_figures_now,
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
