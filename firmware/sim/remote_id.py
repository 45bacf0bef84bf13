"""A Remote ID module on the simulated autopilot's MAVLink bus, sans-I/O.

It takes the Open Drone ID messages a ground station sends (OPEN_DRONE_ID_BASIC_ID,
OPERATOR_ID, SELF_ID, SYSTEM [MAVLink ODID]), keeps the latest of each and logs every
change, and answers OPEN_DRONE_ID_ARM_STATUS: status 0 (good to arm) or 1 with the reason,
as a transponder does. It fails when told to (`--remote-id-fail REASON`), or when it has
had no Basic ID or no Operator ID for `timeout_s` wall-clock seconds (the ground station's
static messages stopped, so nothing true is being broadcast).
"""

from __future__ import annotations

import logging
from collections import Counter
from dataclasses import dataclass, field
from typing import Any

log = logging.getLogger(__name__)

INPUTS = (
    "OPEN_DRONE_ID_BASIC_ID",
    "OPEN_DRONE_ID_OPERATOR_ID",
    "OPEN_DRONE_ID_SELF_ID",
    "OPEN_DRONE_ID_SYSTEM",
)
REQUIRED = {"OPEN_DRONE_ID_BASIC_ID": "Basic ID", "OPEN_DRONE_ID_OPERATOR_ID": "Operator ID"}
# MAV_ODID_ARM_STATUS
GOOD_TO_ARM = 0
PRE_ARM_FAIL_GENERIC = 1
# ASTM F3411 has static messages (Basic ID, Operator ID) sent at least every 3 s.
DEFAULT_TIMEOUT_S = 5.0
ERROR_LENGTH = 50  # OPEN_DRONE_ID_ARM_STATUS.error is char[50]


def _jsonable(value: Any) -> Any:
    if isinstance(value, bytes | bytearray):
        return value.rstrip(b"\0").decode("ascii", "replace")
    if isinstance(value, list | tuple):
        if all(isinstance(v, int) for v in value):
            return bytes(v & 0xFF for v in value).rstrip(b"\0").decode("ascii", "replace")
        return [_jsonable(v) for v in value]
    return value


@dataclass
class RemoteIdModule:
    fail_reason: str | None = None
    timeout_s: float = DEFAULT_TIMEOUT_S
    # Latest fields of each ODID message received, and how many of each came.
    received: dict[str, dict] = field(default_factory=dict)
    counts: Counter[str] = field(default_factory=Counter)
    _last_at: dict[str, float] = field(default_factory=dict)
    _now: float | None = None
    _since: float | None = None

    def consume(self, msg: Any, now: float) -> None:
        """One ODID message from the ground station."""
        kind = msg.get_type()
        if kind not in INPUTS:
            return
        fields = {
            name: _jsonable(getattr(msg, name))
            for name in msg.get_fieldnames()
            if name not in ("target_system", "target_component")
        }
        self.counts[kind] += 1
        self._last_at[kind] = now
        if self.received.get(kind) != fields:
            log.info("Remote ID %s: %s", kind, fields)
            self.received[kind] = fields

    def tick(self, now: float) -> None:
        if self._since is None:
            self._since = now
        self._now = now

    def arm_status(self) -> tuple[int, str]:
        """(MAV_ODID_ARM_STATUS, error text) as the module would send it now."""
        if self.fail_reason:
            return PRE_ARM_FAIL_GENERIC, self.fail_reason[:ERROR_LENGTH]
        now = self._now if self._now is not None else 0.0
        for kind, name in REQUIRED.items():
            last = self._last_at.get(kind, self._since if self._since is not None else now)
            if now - last > self.timeout_s:
                return PRE_ARM_FAIL_GENERIC, f"no {name} for {now - last:.0f} s"[:ERROR_LENGTH]
        missing = [name for kind, name in REQUIRED.items() if kind not in self.received]
        if missing:
            return PRE_ARM_FAIL_GENERIC, f"waiting for {' and '.join(missing)}"
        return GOOD_TO_ARM, ""
