"""Software-in-the-loop flight controller: dRonin (UAVTalk over a pty or TCP) or, with
`fc="mavlink"`, an ArduCopter-like MAVLink autopilot on TCP.

`start_simulator(...)` runs one as a subprocess; `vehicle.Vehicle` is the pure model.
"""

from __future__ import annotations

from typing import Any

from firmware.sim.launcher import SimulatorError, SimulatorProcess
from firmware.sim.launcher import start_simulator as _start_uavtalk_or_any


def start_simulator(*args: Any, fc: str = "uavtalk", **kwargs: Any) -> SimulatorProcess:
    """Run `python -m firmware.sim` (see launcher.start_simulator for the arguments).

    `fc="mavlink"` serves MAVLink on TCP (any free port unless `tcp_port` is given, or a
    pty with `extra_args=["--serial"]`); the returned process's `.link_url` (= `.url`) is
    what a driver opens.
    """
    if fc not in ("uavtalk", "mavlink"):
        raise ValueError(f"unknown simulator personality {fc!r}")
    if fc == "mavlink":
        extra = list(kwargs.pop("extra_args", None) or [])
        if "--serial" not in extra and kwargs.get("tcp_port") is None:
            kwargs["tcp_port"] = 0
        kwargs["extra_args"] = ["--fc", "mavlink", *extra]
    sim = _start_uavtalk_or_any(*args, **kwargs)
    sim.link_url = sim.url  # type: ignore[attr-defined]
    return sim


__all__ = ["SimulatorError", "SimulatorProcess", "start_simulator"]
