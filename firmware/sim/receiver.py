"""The flight controller's arming decision from receiver input.

dRonin arms only from receiver inputs. PPM frames (the arming line) are read as
onboard/arming_frames.json defines them: throttle low with yaw right held for the arming
time arms, throttle low with yaw left held for the disarming time disarms.
UAVTalkReceiver channels (`BoardChannels`) are read through the board's
ManualControlSettings (onboard.uavtalk.receiver_setup): a stick gesture held for the
arming time, or for `Switch+Throttle` / `Switch` the arming channel high (with the
throttle low) for ArmTime, low for DisarmTime to disarm; after a cancelled attempt the
switch must go low before it arms again.
"""

from __future__ import annotations

from collections.abc import Sequence

from onboard.arming_frames import Frames, load_frames
from onboard.uavtalk import receiver_setup

DISARMED, ARMING, ARMED = "Disarmed", "Arming", "Armed"


class BoardChannels(list):
    """UAVTalkReceiver channel values with the ManualControlSettings they are read by."""

    def __init__(self, channels: Sequence[int], settings: dict) -> None:
        super().__init__(channels)
        self.settings = settings

    @property
    def switch(self) -> bool:
        return self.settings["Arming"] in receiver_setup.SWITCH_OPTIONS

    def times(self) -> tuple[float, float]:
        """ArmTime and DisarmTime in seconds."""
        return tuple(float(self.settings[k]) / 1000 for k in ("ArmTime", "DisarmTime"))  # type: ignore[return-value]


class ReceiverArming:
    """Feed it receiver frames (pulse HIGH times, µs, in arming_frames.json channel order).

    `now` is the flight controller's clock in seconds (simulated time in the simulator),
    so the arming time scales with the simulation. Set `airborne` to refuse disarming in
    flight; a frame with a channel out of the accepted range counts as no input.
    """

    def __init__(
        self,
        frames: Frames | None = None,
        *,
        arming_time_s: float | None = None,
        disarming_time_s: float | None = None,
    ) -> None:
        self.frames = frames or load_frames()
        self.arming_time_s = self.frames.arming_time_s if arming_time_s is None else arming_time_s
        self.disarming_time_s = (
            self.frames.disarming_time_s if disarming_time_s is None else disarming_time_s
        )
        self._throttle = self.frames.channel_index("throttle")
        self._yaw = self.frames.channel_index("yaw")
        self._lo = self.frames.pulse_min_us - self.frames.pulse_margin_us
        self._hi = self.frames.pulse_max_us + self.frames.pulse_margin_us
        self.state = DISARMED
        self.airborne = False
        self.refused_disarms = 0
        self._held_since: float | None = None
        self._holding: str | None = None
        # Switch family: an arming attempt was cancelled; the switch must go low first.
        self.switch_must_drop = False
        self._switch = False
        # An alarm that vetoes arming (dRonin's ok_to_arm): arming gestures are ignored.
        self.vetoed = False

    def reset(self) -> None:
        """Back to Disarmed, as after a reboot."""
        self.state = DISARMED
        self._held_since = None
        self._holding = None
        self.switch_must_drop = False

    def _gesture(self, pulses_us: Sequence[int]) -> str | None:
        if isinstance(pulses_us, BoardChannels):
            return receiver_setup.gesture(pulses_us.settings, pulses_us)
        needed = max(self._throttle, self._yaw) + 1
        if len(pulses_us) < needed or any(
            not self._lo <= p <= self._hi for p in pulses_us[:needed]
        ):
            return None
        throttle, yaw = pulses_us[self._throttle], pulses_us[self._yaw]
        if throttle > self.frames.throttle_low_max_us:
            return None
        if yaw >= self.frames.yaw_arm_min_us:
            return "arm"
        if yaw <= self.frames.yaw_disarm_max_us:
            return "disarm"
        return None

    def _times(self, pulses_us: Sequence[int]) -> tuple[float, float]:
        if isinstance(pulses_us, BoardChannels):
            # Kept while the channels go quiet: the board's option does not change then.
            self._switch = pulses_us.switch
            if self._switch:
                return pulses_us.times()
        return self.arming_time_s, self.disarming_time_s

    def feed(self, pulses_us: Sequence[int], now: float) -> str:
        """Apply one receiver frame seen at time `now`; return the arming state after it."""
        gesture = self._gesture(pulses_us)
        arming_time_s, disarming_time_s = self._times(pulses_us)
        if gesture == "disarm" and isinstance(pulses_us, BoardChannels) and self._switch:
            self.switch_must_drop = False  # the switch is low
        elif gesture == "arm" and (self.switch_must_drop or self.vetoed):
            gesture = None
        wanted = {"arm": DISARMED, "disarm": ARMED}
        if gesture is None or not (
            self.state == wanted[gesture] or (self.state == ARMING and gesture == "arm")
        ):
            self._holding = None
            self._held_since = None
            if self.state == ARMING:
                self.state = DISARMED  # sticks released before the arming time
                self.switch_must_drop = self._switch and gesture != "disarm"
            return self.state
        if self._holding != gesture:
            self._holding = gesture
            self._held_since = now
        held = now - (self._held_since if self._held_since is not None else now)
        if gesture == "arm":
            if held >= arming_time_s:
                self.state = ARMED
                self._holding = None
            else:
                self.state = ARMING
        elif held >= disarming_time_s:
            if self.airborne:
                self.refused_disarms += 1
                self._held_since = now  # keep refusing until landed
            else:
                self.state = DISARMED
                self._holding = None
        return self.state
