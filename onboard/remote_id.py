"""Remote ID on the drone (docs/remote-id.md): the identity the ground sends with the
envelope goes to the flight controller's Remote ID module, and the module's health goes
into every heartbeat.

On a MAVLink flight controller the agent sends OPEN_DRONE_ID_BASIC_ID, OPERATOR_ID,
SELF_ID and SYSTEM once a second (ASTM F3411 asks for the static messages at least every
3 s [ASTM F3411]) and reads OPEN_DRONE_ID_ARM_STATUS back [MAVLink ODID]: status 0 is
healthy, any other is a failure with the module's own words; no arm status for
ARM_STATUS_TIMEOUT_S while it has an identity to broadcast is a failure too. A flight
controller without Open Drone ID (UAVTalk) reports nothing: the ground relies on an
admin's declaration that an external module is fitted.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from typing import Any

from .protocol import RemoteIdentity, RemoteIdHealth

log = logging.getLogger(__name__)

SEND_INTERVAL_S = 1.0
ARM_STATUS_TIMEOUT_S = 3.0


class RemoteId:
    """Keeps the identity, sends it while the link is up and tracks the arm status."""

    def __init__(
        self,
        fc: Any,
        *,
        interval: float = SEND_INTERVAL_S,
        timeout: float = ARM_STATUS_TIMEOUT_S,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.fc = fc
        self.interval = interval
        self.timeout = timeout
        self.clock = clock
        self.sent = 0
        self._identity: RemoteIdentity | None = None
        self._identity_at = 0.0
        self._status: tuple[bool, str] | None = None
        self._status_at = 0.0
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    @property
    def speaks_odid(self) -> bool:
        return getattr(self.fc, "protocol", "") == "mavlink"

    def start(self) -> None:
        if not self.speaks_odid:
            return
        self.fc.add_message_handler(self._on_message)
        self._thread = threading.Thread(target=self._run, name="remote-id", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(2)

    def set_identity(self, identity: RemoteIdentity | None) -> None:
        with self._lock:
            if identity != self._identity:
                self._identity = identity
                self._identity_at = self.clock()
                log.info("Remote ID identity: %s", None if identity is None else identity)

    def health(self) -> RemoteIdHealth | None:
        """What the heartbeat reports: the module's last arm status while fresh; a failure
        when an identity waits for a module that does not answer; None when nothing is
        known (no module heard, no identity)."""
        if not self.speaks_odid:
            return None
        now = self.clock()
        with self._lock:
            status, status_at = self._status, self._status_at
            identity, since = self._identity, self._identity_at
        if status is not None and now - status_at <= self.timeout:
            return RemoteIdHealth(ok=status[0], error=status[1])
        if identity is None:
            return None
        silent = now - max(status_at, since)
        if status is None and silent <= self.timeout:
            return None  # just given an identity: the module has not had time to answer
        return RemoteIdHealth(
            ok=False,
            error=f"no OPEN_DRONE_ID_ARM_STATUS from a Remote ID module for {silent:.0f} s",
        )

    def _on_message(self, msg: Any) -> None:
        if msg.get_type() != "OPEN_DRONE_ID_ARM_STATUS":
            return
        from .fc import odid

        status = odid.arm_status({"status": msg.status, "error": msg.error})
        with self._lock:
            if status != self._status:
                log.info("Remote ID arm status: %s", "good" if status[0] else status[1])
            self._status, self._status_at = status, self.clock()

    def _operator_position(self, identity: RemoteIdentity) -> tuple[float, float] | None:
        if identity.operator_location is not None:
            return identity.operator_location
        home = self.fc.state.home
        return None if home is None else (home[0], home[1])

    def _send_once(self) -> None:
        from .fc import odid

        with self._lock:
            identity = self._identity
        if identity is None or not self.fc.state.connected:
            return
        odid.send_identity(self.fc, identity, self._operator_position(identity), time.time())
        self.sent += 1

    def _run(self) -> None:
        while not self._stop.wait(self.interval):
            try:
                self._send_once()
            except Exception:  # a closed link mid-send: the next round tries again
                log.debug("could not send Remote ID messages", exc_info=True)
