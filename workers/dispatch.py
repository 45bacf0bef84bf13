"""Which domain function handles each drone → ground channel (the gateway's one table).

A handler is `handler(drone_id: str, message) -> str | None`: `message` is already
parsed by `onboard.protocol` (the parser for that channel), and the drone id is the
topic's, which the broker's ACL ties to the drone's credentials. It returns None when the
message was taken, or a short reason (`"unknown_drone"`) when it was dropped; the gateway
counts `dropped.<reason>`. Channels mapped to None are received and counted only.
Telemetry is not here: it has its own ingest process.
"""

from __future__ import annotations

DISPATCH: dict[str, str | None] = {
    "heartbeats": "fleet.heartbeats.handle_heartbeat",
    "gear": "fleet.heartbeats.handle_gear",
    "control": "fleet.commands.handle_control_reply",
    "mission": "missions.reports.handle_mission",
    "alarms": "missions.reports.handle_alarm",
    "pictures": "missions.reports.handle_picture",
    # "camera" is not here: `manage.py pastview` (pastview/runner.py) reads the
    # frames with the pose stream, so the gateway need not receive them at all.
}

# Bigger payloads are dropped before parsing (pictures carry a JPEG, base64-encoded).
MAX_PAYLOAD_BYTES: dict[str, int] = {
    "pictures": 16 * 1024 * 1024,
    "camera": 4 * 1024 * 1024,
}
DEFAULT_MAX_PAYLOAD_BYTES = 256 * 1024

# Channels whose handler takes a whole batch:
# `handler(batch: list[tuple[str, message]]) -> list[str | None]` (a reason per message).
# The gateway feeds them from a worker thread, so a flood costs one statement per batch
# and paho's network thread never waits on the database. A channel in both tables goes to
# its batch handler (the single one serves gateways built with a custom `dispatch`).
BATCH_DISPATCH: dict[str, str] = {
    "heartbeats": "fleet.heartbeats.handle_heartbeats",
}
# Messages per batch at most: the statement writes one row per drone (its newest), so a
# large batch of a flood costs little more than a small one.
MAX_BATCH = 5000
# Parsed messages waiting for a batch handler; beyond this they are dropped as overload.
MAX_QUEUED = 50_000
