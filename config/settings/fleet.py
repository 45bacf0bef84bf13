"""The drone link: heartbeats, going offline, commands and their answers, live fleet pushes."""

from __future__ import annotations

from config.env import env

# Heartbeats every 5 s; offline after 3 missed ones (docs/protocol.md).
HEARTBEAT_INTERVAL_S = env.float("HEARTBEAT_INTERVAL_S", 5.0)
OFFLINE_AFTER_MISSED_HEARTBEATS = env.int("OFFLINE_AFTER_MISSED_HEARTBEATS", 3)
# The offline sweep (fleet.sweep_offline) runs this often under Celery beat.
OFFLINE_SWEEP_INTERVAL_S = env.float("OFFLINE_SWEEP_INTERVAL_S", 2.0)
# Live fleet updates: at most one per drone per this many seconds (state changes always).
FLEET_PUSH_INTERVAL_S = env.float("FLEET_PUSH_INTERVAL_S", 1.0)

COMMAND_TIMEOUT_S = env.float("COMMAND_TIMEOUT_S", 15.0)
# A command answered within this many seconds is logged once, with its answer; one still
# waiting then is logged as pending at that moment and completed when it ends.
COMMAND_LOG_PENDING_AFTER_S = env.float("COMMAND_LOG_PENDING_AFTER_S", 0.1)
# Commands from web processes go over each process's own broker connection (the ground's
# MQTT_URL account; workers.direct), falling back to the gateways' outbox when it is down
# or the broker has not acknowledged a command within COMMAND_DIRECT_PUBACK_S seconds.
COMMAND_DIRECT = env.bool("COMMAND_DIRECT", True)
COMMAND_DIRECT_PUBACK_S = env.float("COMMAND_DIRECT_PUBACK_S", 0.5)
# `/control`'s startchain / stopchain start and stop a tracked mission; the fleet app
# names them here because it must not import the missions app that builds on it.
MISSION_START_STOP_HANDLERS = {
    "startchain": "missions.startstop.start_from_control",
    "stopchain": "missions.startstop.stop_from_control",
}
