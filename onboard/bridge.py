"""The drone's internal Mosquitto broker, bridged to the ground broker.

The bridge relays the drone's own `<id>/control|mission|gear/in` topics in and every
`+/<channel>/out` topic out (docs/protocol.md, "Internal broker"), logging in
to the ground broker with the drone's own credentials.

`python -m onboard.bridge --drone-id ID --ground mqtt://ID:PASS@host:1883 [--port 1884]`
prints a complete mosquitto.conf for the internal broker.
"""

from __future__ import annotations

import argparse
import sys

from . import protocol
from .mqtt import parse_broker_url


def _quote(value: str) -> str:
    # Mosquitto config values end at the newline; refuse anything that could inject lines.
    if any(c in value for c in "\r\n\0"):
        raise ValueError("bridge settings must not contain line breaks")
    return value


def state_topic(drone_id: str) -> str:
    """Where the internal broker publishes the bridge's state (give it to --ground-link-topic)."""
    return f"$SYS/broker/connection/droneMosquitto-{drone_id}/state"


def bridge_config(
    drone_id: str,
    ground_url: str,
    *,
    connection: str = "groundRelay",
    keepalive: int = 10,
) -> str:
    """The `connection` section for the internal broker's mosquitto.conf."""
    if not protocol.is_drone_id(drone_id):
        raise ValueError(f"{drone_id!r} is not a valid drone id")
    broker = parse_broker_url(ground_url)
    if not broker.username or not broker.password:
        raise ValueError("the ground broker URL must carry the drone's username and password")
    lines = [
        f"connection {_quote(connection)}",
        f"address {_quote(broker.host)}:{broker.port}",
        f"remote_username {_quote(broker.username)}",
        f"remote_password {_quote(broker.password)}",
        f"remote_clientid droneMosquitto-{drone_id}",
        "cleansession false",
        f"keepalive_interval {keepalive}",
        "restart_timeout 1 10",
        "try_private true",
        # The bridge announces its own state ("1" up, "0" down, retained) on the internal
        # broker only; the agent watches it to know when the ground link is lost.
        "notifications true",
        "notifications_local_only true",
        f"notification_topic {state_topic(drone_id)}",
    ]
    if broker.tls:
        lines.append("bridge_capath /etc/ssl/certs")
    for channel in protocol.IN_CHANNELS:
        lines.append(f'topic {drone_id}/{channel}/in in 1 "" ""')
    for channel in protocol.OUT_CHANNELS:
        lines.append(f'topic +/{channel}/out out {protocol.QOS[channel] or 0} "" ""')
    return "\n".join(lines) + "\n"


def internal_broker_config(
    drone_id: str,
    ground_url: str,
    *,
    port: int = 1883,
    bind: str = "127.0.0.1",
    persistence_dir: str | None = None,
) -> str:
    """A whole mosquitto.conf: a local listener for the drone's processes plus the bridge."""
    lines = [
        f"listener {port} {bind}",
        "allow_anonymous true",
        "set_tcp_nodelay true",
    ]
    if persistence_dir:
        lines += ["persistence true", f"persistence_location {_quote(persistence_dir)}/"]
    return "\n".join(lines) + "\n\n" + bridge_config(drone_id, ground_url)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m onboard.bridge", description=__doc__)
    p.add_argument("--drone-id", required=True)
    p.add_argument("--ground", required=True, help="mqtt://ID:PASSWORD@host:port")
    p.add_argument("--port", type=int, default=1883, help="internal listener port")
    p.add_argument("--bind", default="127.0.0.1")
    p.add_argument("--persistence-dir")
    args = p.parse_args(argv)
    try:
        text = internal_broker_config(
            args.drone_id,
            args.ground,
            port=args.port,
            bind=args.bind,
            persistence_dir=args.persistence_dir,
        )
    except ValueError as exc:
        print(f"onboard.bridge: {exc}", file=sys.stderr)
        return 2
    sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
