"""The MQTT broker the ground and the drones meet on (docs/scaling.md)."""

from __future__ import annotations

from django.core.exceptions import ImproperlyConfigured

from config.env import BASE_DIR, env

MQTT_URL = env.str("MQTT_URL", "mqtt://ground:ground@127.0.0.1:1883")
# The ground broker: "mosquitto" (one node, the default) or "rabbitmq" (MQTT plugin,
# clusterable; docs/scaling.md). With several nodes, MQTT_URLS lists every node's MQTT
# listener in the order clients try them; AMQP_URLS are the same nodes' AMQP listeners
# (the gateway and ingest consume from shared queues there, as RabbitMQ 3.10's MQTT
# plugin has no shared subscriptions); RABBITMQ_API_URLS their management APIs (per-drone
# users and permissions, queue depths on the status page).
MQTT_BROKER = env.str("MQTT_BROKER", "mosquitto")
if MQTT_BROKER not in ("mosquitto", "rabbitmq"):
    raise ImproperlyConfigured(f"MQTT_BROKER must be mosquitto or rabbitmq, not {MQTT_BROKER!r}")
MQTT_URLS = env.list("MQTT_URLS", cast=str.strip, default=[MQTT_URL])
AMQP_URLS = env.list("AMQP_URLS", cast=str.strip, default=[])
RABBITMQ_API_URLS = env.list("RABBITMQ_API_URLS", cast=str.strip, default=[])
# Where Mosquitto's password and ACL files live, and its pid file for the SIGHUP reload.
MOSQUITTO_DIR = env.str("MOSQUITTO_DIR", str(BASE_DIR / ".data" / "run" / "mosquitto"))
# Broker users kept in Mosquitto's passwd file when it is regenerated from the drones.
MQTT_SERVICE_USERS = env.list("MQTT_SERVICE_USERS", cast=str.strip, default=["ground"])
# What provision_drone tells a drone to connect to (default: MQTT_URL's host and port).
MQTT_PUBLIC_HOST = env.str("MQTT_PUBLIC_HOST", "")
MQTT_PUBLIC_PORT = env.int("MQTT_PUBLIC_PORT", 0)
# Drones are told mqtts:// URLs: MQTT_PUBLIC_PORT is then Mosquitto's TLS listener
# (MQTT_TLS_PORT of scripts/services.sh).
MQTT_PUBLIC_TLS = env.bool("MQTT_PUBLIC_TLS", False)
