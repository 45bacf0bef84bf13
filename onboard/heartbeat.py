"""Heartbeats (every 5 s, docs/protocol.md) and the drone id derived from the MAC address."""

from __future__ import annotations

import logging
import re
import threading
import time
import uuid
from collections.abc import Callable
from pathlib import Path

from . import protocol
from .fc.base import VehicleState

log = logging.getLogger(__name__)

DEFAULT_PREFIX = "DRONE"
SYS_NET = Path("/sys/class/net")


def first_mac_address(sys_net: Path = SYS_NET) -> bytes | None:
    """The MAC of the first non-loopback adapter (by name), or None when there is none."""
    try:
        names = sorted(p.name for p in sys_net.iterdir())
    except OSError:
        return None
    for name in names:
        if name == "lo":
            continue
        try:
            text = (sys_net / name / "address").read_text().strip()
        except OSError:
            continue
        raw = (
            bytes.fromhex(text.replace(":", ""))
            if re.fullmatch(r"([0-9a-f]{2}:){5}[0-9a-f]{2}", text)
            else b""
        )
        if len(raw) == 6 and any(raw):
            return raw
    return None


def derive_drone_id(prefix: str = DEFAULT_PREFIX, mac: bytes | None = None) -> str:
    """`<PREFIX>_<XXXXXX>`: upper-case hex of the MAC's last 3 bytes (docs/protocol.md, "Identity and units")."""
    if mac is None:
        mac = first_mac_address()
    if mac is None:
        mac = uuid.getnode().to_bytes(6, "big")
    drone_id = f"{prefix}_{mac[-3:].hex().upper()}"
    if not protocol.is_drone_id(drone_id):
        raise ValueError(f"prefix {prefix!r} does not make a valid drone id")
    return drone_id


def build_heartbeat(
    drone_id: str,
    state: VehicleState,
    mission: protocol.MissionRef | None,
    remote_id: protocol.RemoteIdHealth | None = None,
) -> protocol.Heartbeat:
    position = None
    if state.lat is not None and state.lon is not None:
        position = protocol.Position(state.lat, state.lon, state.alt or 0.0)
    return protocol.Heartbeat(
        drone_id=drone_id,
        ts=time.time(),
        position=position,
        battery_voltage=state.battery_voltage,
        battery_remaining=state.battery_remaining,
        armed=state.armed,
        airborne=state.airborne,
        flight_mode=state.flight_mode,
        mission=mission,
        fc_protocol=state.protocol,
        fc_connected=state.connected,
        fc_setup=state.setup,
        remote_id=remote_id,
        battery_serial=state.battery_serial,
    )


class Heartbeater:
    """Publishes a heartbeat at once and then every `interval` seconds."""

    def __init__(self, interval: float, beat: Callable[[], None]) -> None:
        self.interval = interval
        self.beat = beat
        self.sent = 0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        self._thread = threading.Thread(target=self._run, name="heartbeat", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(2)

    def _run(self) -> None:
        # A monotonic schedule: a slow beat does not push every later beat back.
        next_at = time.monotonic()
        while not self._stop.is_set():
            try:
                self.beat()
                self.sent += 1
            except Exception:
                log.exception("heartbeat failed")
            next_at += self.interval
            self._stop.wait(max(0.0, next_at - time.monotonic()))
