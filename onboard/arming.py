"""Arming Switch backends: dRonin arms only from receiver inputs, never from a command.

Every backend offers `request_arm()`, `request_disarm()` and `release()`; the flight
controller driver calls them and waits for FlightStatus.Armed, which is the only truth.
Backends:

- `SimulatedLine(path)`: the simulator's arming line, a two-character file: request pin
  then mode pin ("00" idle, "10" request arm, "11" request disarm).
- `GpiodLine(chip, request_line, mode_line)`: the Arduino arming-switch emulator's request
  and mode pins on a Linux GPIO character device (the `gpiod` package).
- `UAVTalkReceiverSwitch(fc)`: for boards whose receiver group is UAVTalk, the arming
  switch or stick positions written as `UAVTalkReceiver` channel values at 25 Hz, in the
  board's own scale and channel numbers once its ManualControlSettings are known.
"""

from __future__ import annotations

import logging
import os
import threading
import time
from pathlib import Path
from typing import Any, Protocol

from .arming_frames import load_frames
from .uavtalk import receiver_setup

log = logging.getLogger(__name__)


class ArmingError(Exception):
    """A backend that cannot be used (missing library, bad chip or line)."""


class ArmingSwitch(Protocol):
    def request_arm(self) -> None: ...

    def request_disarm(self) -> None: ...

    def release(self) -> None: ...


class SimulatedLine:
    """The simulator's arming line: request pin then mode pin, as two characters."""

    IDLE, ARM, DISARM = "00", "10", "11"

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.history: list[tuple[float, str]] = []
        self._write(self.IDLE)

    def _write(self, value: str) -> None:
        # Overwrite both characters in one pwrite, never truncate: a reader polling the
        # file must never see it empty or half written.
        fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            os.pwrite(fd, value.encode("ascii"), 0)
            if os.fstat(fd).st_size > len(value):
                os.ftruncate(fd, len(value))
        finally:
            os.close(fd)
        self.history.append((time.time(), value))

    def request_arm(self) -> None:
        self._write(self.ARM)

    def request_disarm(self) -> None:
        self._write(self.DISARM)

    def release(self) -> None:
        self._write(self.IDLE)

    @property
    def value(self) -> str:
        return self.path.read_text()


class GpiodLine:
    """Request and mode pins of the arming-switch emulator via the GPIO character device."""

    def __init__(self, chip: str, request_line: int, mode_line: int) -> None:
        try:
            import gpiod  # type: ignore[import-not-found]
        except ImportError:
            raise ArmingError(
                "The arming switch over GPIO needs gpiod: pip install 'skyhive-onboard[gpio]'"
            ) from None
        if request_line == mode_line:
            raise ArmingError("The request and mode lines must be different GPIO lines.")
        chip_path = chip if chip.startswith("/") else f"/dev/{chip}"
        if not os.path.exists(chip_path):
            raise ArmingError(f"GPIO chip {chip_path} does not exist.")
        self._gpiod = gpiod
        self._request_line = request_line
        self._mode_line = mode_line
        self._lines = self._open(chip_path)
        self.release()

    def _open(self, chip_path: str) -> Any:
        gpiod = self._gpiod
        lines = (self._request_line, self._mode_line)
        if hasattr(gpiod, "request_lines"):  # libgpiod 2.x bindings
            from gpiod.line import Direction, Value  # type: ignore[import-not-found]

            self._values = (Value.INACTIVE, Value.ACTIVE)
            return gpiod.request_lines(
                chip_path,
                consumer="skyhive-arming",
                config={lines: gpiod.LineSettings(direction=Direction.OUTPUT)},
            )
        self._values = (0, 1)  # libgpiod 1.x bindings
        bulk = gpiod.Chip(chip_path).get_lines(list(lines))
        bulk.request(consumer="skyhive-arming", type=gpiod.LINE_REQ_DIR_OUT)
        return bulk

    def _set(self, request: int, mode: int) -> None:
        low, high = self._values
        values = (high if request else low, high if mode else low)
        if hasattr(self._lines, "set_values") and hasattr(self._gpiod, "request_lines"):
            self._lines.set_values(
                dict(zip((self._request_line, self._mode_line), values, strict=True))
            )
        else:
            self._lines.set_values(list(values))

    def request_arm(self) -> None:
        self._set(1, 0)

    def request_disarm(self) -> None:
        self._set(1, 1)

    def release(self) -> None:
        self._set(0, 0)


class UAVTalkReceiverSwitch:
    """Sends the arming positions as UAVTalkReceiver channels at 25 Hz until released.

    With the board's ManualControlSettings (`configure`, done by the driver on connect)
    the channels follow its `Arming` option, channel numbers and scale
    (onboard.uavtalk.receiver_setup): the arming channel high or low for the switch
    family, the option's stick gesture otherwise. Without them (not readable) it sends
    the fixed frames of arming_frames.json for `Yaw Right+Throttle`.

    A real board reads a receiver group that goes quiet as lost (it wants 20-50 Hz,
    docs/uavtalk.md "Arming"); the writes are not acknowledged, as the definition says.

    When the board refuses (an alarm keeps it disarmed, FlightStatus drops back from
    Arming), the sticks go back to neutral for a moment and the request starts again, as a
    pilot would do.

    Released while the board is armed, it keeps sending the rest position at the same
    rate until the board disarms or `close()`: a dRonin board whose channels stop reads
    its transmitter as disconnected and hands control to Failsafe
    (flight/Modules/ManualControl/manualcontrol.c, control_source_select).
    """

    CHANNELS = 8
    # The channels come over the telemetry link itself, not a radio: full signal strength.
    RSSI = 65535
    SWITCH_LOW_TICKS = 5
    # The board's receiver group these channels arrive in: the driver checks on connect
    # that the board reads its sticks from it (onboard.uavtalk.receiver_setup).
    receiver_group = "UAVTalk"

    def __init__(self, fc: Any = None, *, rate_hz: float = 25.0, frames: Any = None) -> None:
        if frames is None:
            frames = load_frames()
        self.fc = fc
        self.frames = frames
        self.period = 1.0 / rate_hz
        self.retries = 0
        self.settings: dict | None = None
        self._mode: str | None = None
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self._thread: threading.Thread | None = None

    def attach(self, fc: Any) -> None:
        """Give the switch its flight controller (the driver is built after the switch)."""
        self.fc = fc

    def configure(self, settings: dict | None) -> None:
        """The board's ManualControlSettings (None: unknown, send the fixed frames)."""
        known = settings is not None and (
            settings.get("Arming") in receiver_setup.SWITCH_OPTIONS
            or settings.get("Arming") in receiver_setup.GESTURES
        )
        self.settings = dict(settings) if known else None  # type: ignore[arg-type]

    def channels(self, frame: str) -> list[int]:
        """Channel values for 'arm', 'disarm' or 'safe'."""
        settings = self.settings
        if settings is not None:
            if frame == "safe" and settings["Arming"] in receiver_setup.SWITCH_OPTIONS:
                # A switch board disarms on a low switch: at rest the switch stays where
                # the board is, high while armed and low otherwise.
                armed = bool(getattr(getattr(self.fc, "state", None), "armed", False))
                frame = "arm" if armed else "safe"
            return receiver_setup.channel_values(settings, frame)
        pulses = {
            "arm": self.frames.arm_frame_us,
            "disarm": self.frames.disarm_frame_us,
            "safe": self.frames.safe_frame_us,
        }[frame]
        values = [self.frames.to_channel_period_us(p) for p in pulses]
        neutral = self.frames.to_channel_period_us(self.frames.pulse_neutral_us)
        return (values + [neutral] * self.CHANNELS)[: self.CHANNELS]

    def request_arm(self) -> None:
        self._start("arm")

    def request_disarm(self) -> None:
        self._start("disarm")

    def release(self) -> None:
        """Back to the rest position: kept streaming while the board is armed."""
        with self._lock:
            if self._thread is not None and self._armed():
                self._mode = "safe"
                return
        self.close()

    def close(self) -> None:
        """Stop sending (the driver is stopping): one last rest position."""
        with self._lock:
            self._mode = None
            thread, self._thread = self._thread, None
        self._wake.set()
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout=2)
        self._send("safe")

    def _armed(self) -> bool:
        state = getattr(self.fc, "state", None)
        return bool(getattr(state, "armed", False) or getattr(state, "arming", False))

    def _start(self, mode: str) -> None:
        if self.fc is None:
            raise ArmingError("The UAVTalk receiver switch has no flight controller attached.")
        with self._lock:
            self._mode = mode
            if self._thread is None or not self._thread.is_alive():
                self._wake.clear()
                self._thread = threading.Thread(
                    target=self._run, name="arming-receiver", daemon=True
                )
                self._thread.start()

    def _send(self, frame: str) -> bool:
        if self.fc is None:
            return False
        try:
            self.fc.write_object(
                "UAVTalkReceiver",
                {"Channel": self.channels(frame), "RSSI": self.RSSI},
                acked=False,
            )
            return True
        except Exception as exc:  # a refused write is retried on the next tick
            log.debug("UAVTalkReceiver write failed: %s", exc)
            return False

    def _drop_switch(self) -> bool:
        """A switch board arms only on a switch that went low since its last cancelled
        attempt: hold it low for a moment before raising it. True when released."""
        settings = self.settings
        if settings is None or settings["Arming"] not in receiver_setup.SWITCH_OPTIONS:
            return False
        for _ in range(self.SWITCH_LOW_TICKS):
            self._send("disarm")
            if self._wake.wait(self.period):
                return True
        return False

    def _run(self) -> None:
        was_arming = False
        with self._lock:
            first = self._mode
        if first == "arm" and self._drop_switch():
            return
        while True:
            with self._lock:
                mode = self._mode
                if mode == "safe" and not self._armed():
                    self._mode = mode = None  # disarmed at rest: nothing left to hold
                    self._thread = None
            if mode is None:
                return
            state = getattr(self.fc, "state", None)
            arming = bool(getattr(state, "arming", False))
            armed = bool(getattr(state, "armed", False))
            if was_arming and not arming and not armed and mode == "arm":
                # The board left Arming without arming: an alarm refused it. Sticks back
                # to neutral, then try again.
                self.retries += 1
                for _ in range(5):
                    self._send("safe")
                    if self._wake.wait(self.period):
                        return
            was_arming = arming
            self._send(mode)
            if self._wake.wait(self.period):
                return
