"""What a dRonin board's ManualControlSettings must say for the agent to arm it through
UAVTalkReceiver, and what to change when they do not (docs/uavtalk.md "Arming").

The agent's UAVTalk receiver switch writes the arming stick positions of
onboard/arming_frames.json as UAVTalkReceiver channels: channel n of the object is the
n-th channel of `channel_order` (pitch, roll, throttle, yaw), in microseconds, 1000 (low)
to 2000 (high), neutral 1500. Throttle low with yaw right arms; throttle low with yaw left
disarms. So the board must read those four controls from the UAVTalk group, from those
channel numbers, on a scale that turns the values sent into the stick positions meant,
and arm on "Yaw Right+Throttle". `problems` checks exactly that, the way dRonin's
transmitter control scales a channel, and says what to set.
"""

from __future__ import annotations

from collections.abc import Mapping

from onboard.arming_frames import Frames, load_frames

SETTINGS = "ManualControlSettings"
GROUP = "UAVTalk"
ARMING = "Yaw Right+Throttle"
# dRonin's ManualControlSettings element names of the controls the switch moves.
CONTROLS = {"pitch": "Pitch", "roll": "Roll", "throttle": "Throttle", "yaw": "Yaw"}
ELEMENTS = (
    "Throttle",
    "Roll",
    "Pitch",
    "Yaw",
    "FlightMode",
    "Collective",
    "Accessory0",
    "Accessory1",
    "Accessory2",
    "Arming",
)
# A stick counts as moved to one side past half its travel (dRonin's arming threshold).
STICK_THRESHOLD = 0.5


def scale(value: float, low: float, neutral: float, high: float) -> float:
    """A channel value as dRonin scales it: -1 at ChannelMin, 0 at neutral, +1 at max."""
    if value > neutral:
        return (value - neutral) / (high - neutral) if high != neutral else 0.0
    return (value - neutral) / (neutral - low) if neutral != low else 0.0


def _sent(frames: Frames) -> dict[str, dict[str, int]]:
    """Per control, the channel values the switch sends for each gesture."""
    order = frames.channel_order
    gestures = {
        "arm": frames.arm_frame_us,
        "disarm": frames.disarm_frame_us,
        "safe": frames.safe_frame_us,
    }
    return {
        name: {g: frames.to_channel_period_us(p[order.index(name)]) for g, p in gestures.items()}
        for name in CONTROLS
    }


def required(frames: Frames | None = None) -> dict[str, object]:
    """The settings the switch needs, as `ManualControlSettings.<field>.<element>` → value."""
    frames = frames or load_frames()
    low = frames.to_channel_period_us(frames.pulse_min_us)
    neutral = frames.to_channel_period_us(frames.pulse_neutral_us)
    high = frames.to_channel_period_us(frames.pulse_max_us)
    wanted: dict[str, object] = {}
    for name, element in CONTROLS.items():
        wanted[f"ChannelGroups.{element}"] = GROUP
        wanted[f"ChannelNumber.{element}"] = frames.channel_order.index(name) + 1
        wanted[f"ChannelMin.{element}"] = low
        wanted[f"ChannelNeutral.{element}"] = neutral
        wanted[f"ChannelMax.{element}"] = high
    wanted["Arming"] = ARMING
    wanted["FlightModeNumber"] = 1
    return wanted


def correct_settings(base: Mapping[str, object], frames: Frames | None = None) -> dict:
    """`base` (a ManualControlSettings value set) with every required setting applied."""
    values = {k: list(v) if isinstance(v, list) else v for k, v in base.items()}
    for key, value in required(frames).items():
        field, _, element = key.partition(".")
        if element:
            values[field][ELEMENTS.index(element)] = value  # type: ignore[index]
        else:
            values[field] = value
    return values


def _get(settings: Mapping[str, object], field: str, element: str) -> object:
    value = settings[field]
    return value[ELEMENTS.index(element)] if isinstance(value, list) else value


def _fix(key: str, should: object, now: object, why: str = "") -> str:
    return f"set {SETTINGS}.{key} to {should} (it is {now}{why})"


def _scale_problems(settings: Mapping[str, object], frames: Frames) -> list[str]:
    """Scales under which the values sent would not read as the sticks meant."""
    wanted = required(frames)
    found = []
    for name, element in CONTROLS.items():
        low, neutral, high = (
            float(_get(settings, field, element))  # type: ignore[arg-type]
            for field in ("ChannelMin", "ChannelNeutral", "ChannelMax")
        )
        sent = _sent(frames)[name]
        meant = {
            "throttle": [(sent["arm"], lambda s: s <= 0.0)],
            "yaw": [
                (sent["arm"], lambda s: s > STICK_THRESHOLD),
                (sent["disarm"], lambda s: s < -STICK_THRESHOLD),
                (sent["safe"], lambda s: abs(s) < STICK_THRESHOLD),
            ],
        }.get(name, [(sent["safe"], lambda s: abs(s) < STICK_THRESHOLD)])
        if low < high and all(ok(scale(v, low, neutral, high)) for v, ok in meant):
            continue
        for field in ("ChannelMin", "ChannelNeutral", "ChannelMax"):
            key = f"{field}.{element}"
            if _get(settings, field, element) != wanted[key]:
                found.append(_fix(key, wanted[key], _get(settings, field, element)))
    return found


def problems(settings: Mapping[str, object], frames: Frames | None = None) -> list[str]:
    """What to change on the board so the agent can arm it through UAVTalkReceiver
    (empty when nothing); each item names the setting, the value it needs and its value."""
    frames = frames or load_frames()
    wanted = required(frames)
    found = []
    for element in CONTROLS.values():
        for field in ("ChannelGroups", "ChannelNumber"):
            key = f"{field}.{element}"
            if _get(settings, field, element) != wanted[key]:
                found.append(_fix(key, wanted[key], _get(settings, field, element)))
    if settings["Arming"] != ARMING:
        found.append(_fix("Arming", ARMING, settings["Arming"]))
    modes = settings["FlightModeNumber"]
    if modes != 1 and _get(settings, "ChannelGroups", "FlightMode") == "None":
        found.append(_fix("FlightModeNumber", 1, modes, ", with no FlightMode channel"))
    return found + _scale_problems(settings, frames)


def by_hand(frames: Frames | None = None) -> list[str]:
    """Every required setting, for a board whose settings cannot be read."""
    return [f"{SETTINGS}.{key} = {value}" for key, value in required(frames).items()]
