"""A dRonin board's ManualControlSettings for arming through UAVTalkReceiver: what the
agent writes in the board's own scale and channel numbers, how the board reads it, and
what to change when the settings cannot work (docs/uavtalk.md "Arming").

Two families of `Arming` work. The recommended one, `Switch+Throttle` (or `Switch`), reads
an arming channel: high (ChannelMax) with the throttle low for ArmTime arms, low disarms.
The stick gestures (`Yaw Right+Throttle`, `Yaw Left+Throttle`, `Roll Left+Throttle`,
`Roll Right+Throttle`, `Corners+Throttle`) arm with the sticks at one side and the throttle
low, and disarm with the opposite side. Values are scaled the way dRonin's transmitter
control does: -1 at ChannelMin, 0 at ChannelNeutral, +1 at ChannelMax.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from onboard.arming_frames import Frames, load_frames

SETTINGS = "ManualControlSettings"
GROUP = "UAVTalk"
ARMING = "Yaw Right+Throttle"  # what a board is set up for when its settings are unknown
RECOMMENDED = "Switch+Throttle"
SWITCH_OPTIONS = ("Switch+Throttle", "Switch")
# Per stick-gesture option, the side (+1 max, -1 min) each stick is pushed to arm; the
# opposite sides disarm. Corners: yaw right with roll left, as the agent and the
# simulator read it.
GESTURES: dict[str, dict[str, int]] = {
    "Yaw Right+Throttle": {"Yaw": 1},
    "Yaw Left+Throttle": {"Yaw": -1},
    "Roll Right+Throttle": {"Roll": 1},
    "Roll Left+Throttle": {"Roll": -1},
    "Corners+Throttle": {"Yaw": 1, "Roll": -1},
}
STICKS = ("Throttle", "Roll", "Pitch", "Yaw")
# Channel numbers suggested when one is missing: the layout arming_frames.json sends by
# default (pitch, roll, throttle, yaw) with the arming switch next.
SUGGESTED_NUMBER = {"Pitch": 1, "Roll": 2, "Throttle": 3, "Yaw": 4, "Arming": 5}
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
CHANNELS = 8  # UAVTalkReceiver.Channel
NO_DATA = 65535  # a channel with no data: the board raises NoRx and will not arm
# A stick or switch counts as moved to one side past half its travel (dRonin's threshold).
STICK_THRESHOLD = 0.5


def scale(value: float, low: float, neutral: float, high: float) -> float:
    """A channel value as dRonin scales it: -1 at ChannelMin, 0 at neutral, +1 at max
    (a reversed channel, max below min, reads the same way)."""
    if (value - neutral) * (high - neutral) > 0:
        return (value - neutral) / (high - neutral)
    return -(value - neutral) / (low - neutral) if low != neutral else 0.0


def _get(settings: Mapping[str, object], field: str, element: str) -> object:
    value = settings[field]
    return value[ELEMENTS.index(element)] if isinstance(value, list) else value


def controls(settings: Mapping[str, object]) -> tuple[str, ...]:
    """The controls the board's `Arming` option reads."""
    return STICKS + ("Arming",) if settings["Arming"] in SWITCH_OPTIONS else STICKS


def _range(settings: Mapping[str, object], element: str) -> tuple[int, int, int]:
    return tuple(  # type: ignore[return-value]
        int(_get(settings, field, element))  # type: ignore[call-overload]
        for field in ("ChannelMin", "ChannelNeutral", "ChannelMax")
    )


def sides(settings: Mapping[str, object], mode: str) -> dict[str, int]:
    """Per control, where the agent puts it for 'arm', 'disarm' or 'safe': -1 at
    ChannelMin, 0 at neutral, +1 at ChannelMax. The throttle is always low; in the
    switch family the arming channel is high only to arm."""
    wanted = dict.fromkeys(controls(settings), 0)
    wanted["Throttle"] = -1
    if settings["Arming"] in SWITCH_OPTIONS:
        wanted["Arming"] = 1 if mode == "arm" else -1
    else:
        sign = {"arm": 1, "disarm": -1}.get(mode, 0)
        for stick, side in GESTURES.get(str(settings["Arming"]), {}).items():
            wanted[stick] = side * sign
    return wanted


def channel_values(settings: Mapping[str, object], mode: str) -> list[int]:
    """The UAVTalkReceiver channels for 'arm', 'disarm' or 'safe' in the board's scale
    and channel numbers; channels no control reads sit at the pitch neutral, never at
    the no-data value."""
    filler = _range(settings, "Pitch")[1]
    values = [filler] * CHANNELS
    for element, side in sides(settings, mode).items():
        number = int(_get(settings, "ChannelNumber", element))  # type: ignore[call-overload]
        if 1 <= number <= CHANNELS:
            values[number - 1] = _range(settings, element)[side + 1]
    return [min(max(v, 0), NO_DATA - 1) for v in values]


def read(settings: Mapping[str, object], channels: Sequence[int]) -> dict[str, float] | None:
    """The controls as the board reads them from UAVTalkReceiver channels (scaled), or
    None when one of them has no data (NoRx)."""
    found = {}
    for element in controls(settings):
        number = int(_get(settings, "ChannelNumber", element))  # type: ignore[call-overload]
        if not 1 <= number <= min(CHANNELS, len(channels)) or channels[number - 1] == NO_DATA:
            return None
        found[element] = scale(channels[number - 1], *_range(settings, element))
    return found


def gesture(settings: Mapping[str, object], channels: Sequence[int]) -> str | None:
    """'arm', 'disarm' or None, as the board's `Arming` option reads the channels. In the
    switch family 'disarm' means the switch is low (whatever the throttle)."""
    sticks = read(settings, channels)
    option = str(settings["Arming"])
    if sticks is None:
        return None
    low_throttle = sticks["Throttle"] <= 0.0
    if option in SWITCH_OPTIONS:
        if sticks["Arming"] < STICK_THRESHOLD:
            return "disarm"
        return "arm" if low_throttle or option == "Switch" else None
    pushed = GESTURES.get(option)
    if not pushed or not low_throttle:
        return None
    for name, sign in (("arm", 1), ("disarm", -1)):
        if all(sticks[k] * side * sign >= STICK_THRESHOLD for k, side in pushed.items()):
            return name
    return None


def required(frames: Frames | None = None) -> dict[str, object]:
    """The settings today's fixed stick frames need (`Yaw Right+Throttle` on the
    arming_frames.json channels, 1000-2000): what the agent sends when it cannot read the
    board's settings, as `ManualControlSettings.<field>.<element>` → value."""
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
    """`base` with every required setting applied, and an arming channel ready on the
    next channel (so switching `Arming` to `Switch+Throttle` alone is enough)."""
    values = {k: list(v) if isinstance(v, list) else v for k, v in base.items()}
    extra = {"ChannelGroups.Arming": GROUP, "ChannelNumber.Arming": SUGGESTED_NUMBER["Arming"]}
    for key, value in {**required(frames), **extra}.items():
        field, _, element = key.partition(".")
        if element:
            values[field][ELEMENTS.index(element)] = value  # type: ignore[index]
        else:
            values[field] = value
    return values


def _fix(key: str, should: object, now: object, why: str = "") -> str:
    return f"set {SETTINGS}.{key} to {should} (it is {now}{why})"


def _number_problems(settings: Mapping[str, object]) -> list[str]:
    """Channel numbers outside 1-8, or shared by two controls."""
    numbers = {e: _get(settings, "ChannelNumber", e) for e in controls(settings)}
    found: list[str] = []
    owner: dict[object, str] = {}
    for element, number in numbers.items():
        clash = owner.get(number)
        if 1 <= number <= CHANNELS and clash is None:  # type: ignore[operator]
            owner[number] = element
            continue
        taken = {n for e, n in numbers.items() if e != element}
        free = [SUGGESTED_NUMBER[element], *range(1, CHANNELS + 1)]
        should = next(n for n in free if n not in taken)
        why = f", the channel of {clash}" if clash else ", not a channel 1-8"
        found.append(_fix(f"ChannelNumber.{element}", should, number, why))
    return found


def _scale_problems(settings: Mapping[str, object]) -> list[str]:
    """Scales under which the values written cannot read as the positions meant: the
    throttle must reach low, the arming channel high and a gesture stick both sides."""
    found = []
    moved = set(GESTURES.get(str(settings["Arming"]), {}))
    for element in controls(settings):
        low, neutral, high = _range(settings, element)
        if low == high:
            should = low + 1000 if low + 1000 < NO_DATA else low - 1000
            why = f", the same as ChannelMin.{element}"
            found.append(_fix(f"ChannelMax.{element}", should, high, why))
            continue
        at = (neutral - low) / (high - low)  # where the neutral sits, 0 at min, 1 at max
        fine = {"Throttle": 0 <= at <= 1, "Arming": 0 <= at < 1}.get(
            element, 0 < at < 1 if element in moved else True
        )
        if not fine:
            why = f", not between ChannelMin.{element} {low} and ChannelMax.{element} {high}"
            found.append(_fix(f"ChannelNeutral.{element}", (low + high) // 2, neutral, why))
    return found


def problems(settings: Mapping[str, object]) -> list[str]:
    """What to change on the board so the agent can arm it through UAVTalkReceiver
    (empty when nothing); each item names the setting, the value it needs and its value.
    Both families of `Arming` are accepted; an option that cannot arm is told to be
    `Switch+Throttle`, and the rest is checked as if it were."""
    found = []
    option = settings["Arming"]
    if option not in SWITCH_OPTIONS and option not in GESTURES:
        found.append(_fix("Arming", RECOMMENDED, option))
        settings = {**settings, "Arming": RECOMMENDED}
    for element in controls(settings):
        group = _get(settings, "ChannelGroups", element)
        if group != GROUP:
            found.append(_fix(f"ChannelGroups.{element}", GROUP, group))
    found += _number_problems(settings)
    modes = settings["FlightModeNumber"]
    if modes != 1 and _get(settings, "ChannelGroups", "FlightMode") == "None":
        found.append(_fix("FlightModeNumber", 1, modes, ", with no FlightMode channel"))
    return found + _scale_problems(settings)


def by_hand(frames: Frames | None = None) -> list[str]:
    """Every setting the fixed stick frames need, for a board whose settings cannot be
    read (the agent then sends those frames)."""
    return [f"{SETTINGS}.{key} = {value}" for key, value in required(frames).items()]
