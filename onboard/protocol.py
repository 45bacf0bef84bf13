"""The wire contract of docs/protocol.md, in one place: message schemas and strict parsers.

Both sides import this module (the ground too), so it depends on the standard library
only. Every parser takes a decoded JSON object, accepts unknown extra fields, and raises
`ProtocolError` naming the first bad field; nothing here touches MQTT or a socket.
"""

from __future__ import annotations

import base64
import binascii
import json
import logging
import math
import re
import secrets
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import asdict, dataclass, field
from typing import Any, TypeVar

DRONE_ID_RE = re.compile(r"^[A-Za-z0-9_-]{1,64}$")
REQUEST_ID_RE = re.compile(r"^[0-9a-f]{32}$")
OBJECT_NAME_RE = re.compile(r"^[A-Za-z][A-Za-z0-9_]{0,63}$")
MAX_ID_LENGTH = 128
# Text and numbers the ground stores must be storable by PostgreSQL: no NUL, no unpaired
# surrogate, no NaN or infinity, and timestamps between 1970 and 2100 (a clock that far
# off is broken, and a datetime beyond year 9999 cannot even be built).
MAX_TEXT = 10_000
MAX_KEY = 256
MAX_TS = 4_102_444_800.0  # 2100-01-01T00:00:00Z
MAX_DEPTH = 16

# Control commands (docs/protocol.md "Control") and the extra commands a mission step may use.
CONTROL_COMMANDS = (
    "arm",
    "disarm",
    "takeoff",
    "land",
    "changeN",
    "changeE",
    "altitude",
    "navigate",
    "takepic",
    "objrequest",
    "resetfc",
    "rebuildtelemetry",
)
MISSION_ONLY_COMMANDS = ("wait_for_flight", "sleep", "virtualalarm", "sense")
STEP_COMMANDS = CONTROL_COMMANDS + MISSION_ONLY_COMMANDS
# Commands that set a new navigation target (the Navigation Processor's inputs).
NAVIGATION_COMMANDS = ("takeoff", "land", "changeN", "changeE", "altitude", "navigate")

ALARM_LEVELS = ("CRITICAL", "OUT_MEASURE")
MISSION_STATUSES = ("accepted", "rejected", "completed", "stopped")
STEP_STATUSES = ("started", "completed", "failed")
GEAR_QUERIES = ("specs", "sensors", "reading")
# The `error` of a mission the drone stopped itself because a step failed (it was not told
# to stop): "Step 7 (navigate) failed: not armed".
_STEP_FAILURE = re.compile(r"Step (\d+) \((\w+)\) failed: (.*)", re.DOTALL)
MISSION_ACTIONS = ("start", "stop")

DEFAULT_TAKEOFF_ALTITUDE = 10.0
DEFAULT_TOLERANCE = 2.0
MAX_ALTITUDE = 1000.0

# Topic channels, each with the direction it flows (docs/protocol.md "Topics").
IN_CHANNELS = ("control", "mission", "gear", "envelope")
OUT_CHANNELS = (
    "control",
    "mission",
    "gear",
    "heartbeats",
    "alarms",
    "telemetry",
    "camera",
    "pictures",
)
QOS = {
    "control": 1,
    "mission": 1,
    "gear": 1,
    "envelope": 1,
    "alarms": 1,
    "pictures": 1,
    "telemetry": 0,
    "heartbeats": 0,
    "camera": 0,
}


class ProtocolError(ValueError):
    """A message that breaks docs/protocol.md; `field` names the offending field (dotted path)
    and `reason` the kind of fault it is counted under: `malformed`, or one of the faults
    that would poison storage, `bad_text`, `not_finite`, `bad_timestamp`, `too_long`."""

    def __init__(self, field: str, message: str, reason: str = "malformed") -> None:
        super().__init__(f"{field}: {message}")
        self.field = field
        self.message = message
        self.reason = reason


def step_failure(index: int, command: str, error: str | None) -> str:
    """The `error` a drone reports with `stopped` when one of its steps failed."""
    return f"Step {index} ({command}) failed: {error}"


def failed_step(error: str | None) -> tuple[int, str, str] | None:
    """(index, command, why) of the step whose failure stopped a mission, or None when
    the mission was stopped (by the ground, the operator or the fail-safe)."""
    found = _STEP_FAILURE.fullmatch(error or "")
    return None if found is None else (int(found[1]), found[2], found[3])


def new_request_id() -> str:
    """32 lower-case hex characters from 16 cryptographically strong random bytes."""
    return secrets.token_hex(16)


def now() -> float:
    return time.time()


def is_drone_id(value: object) -> bool:
    return isinstance(value, str) and DRONE_ID_RE.match(value) is not None


def topic(drone_id: str, channel: str, direction: str) -> str:
    """`<id>/<channel>/<in|out>`, refusing a channel the contract does not have."""
    if not is_drone_id(drone_id):
        raise ProtocolError("drone_id", f"{drone_id!r} is not a valid drone id")
    channels = IN_CHANNELS if direction == "in" else OUT_CHANNELS if direction == "out" else ()
    if channel not in channels:
        raise ProtocolError("topic", f"no {channel}/{direction} topic in the contract")
    return f"{drone_id}/{channel}/{direction}"


def split_topic(value: str) -> tuple[str, str, str]:
    """`<id>/<channel>/<direction>` → (drone id, channel, direction), or ProtocolError."""
    parts = value.split("/")
    if len(parts) != 3:
        raise ProtocolError("topic", f"{value!r} is not <id>/<channel>/<in|out>")
    drone_id, channel, direction = parts
    topic(drone_id, channel, direction)
    return drone_id, channel, direction


# ---------------------------------------------------------------------------------------
# Field checks. Each names the field it checks, so errors say exactly what is wrong.


def _require(obj: Mapping[str, Any], name: str, prefix: str = "") -> Any:
    if name not in obj:
        raise ProtocolError(prefix + name, "is required")
    return obj[name]


def _object(value: Any, name: str) -> dict:
    if not isinstance(value, dict):
        raise ProtocolError(name, f"must be a JSON object, got {_type_name(value)}")
    return value


def _type_name(value: Any) -> str:
    return {
        type(None): "null",
        bool: "a boolean",
        str: "a string",
        list: "a list",
        dict: "an object",
    }.get(type(value), "a number" if isinstance(value, int | float) else type(value).__name__)


def number(value: Any, name: str, *, lo: float | None = None, hi: float | None = None) -> float:
    """A finite number (numeric strings accepted, as the HTTP endpoint sends them)."""
    if type(value) is float:  # the common case (a JSON number with a fraction): the short way
        result = value
    elif isinstance(value, bool) or value is None:
        raise ProtocolError(name, f"must be a number, got {_type_name(value)}")
    elif isinstance(value, str):
        try:
            result = float(value.strip())
        except ValueError:
            raise ProtocolError(name, f"must be a number, got {value!r}") from None
    elif isinstance(value, int | float):
        try:
            result = float(value)
        except OverflowError:  # a JSON integer beyond float range
            raise ProtocolError(name, "must be a finite number", "not_finite") from None
    else:
        raise ProtocolError(name, f"must be a number, got {_type_name(value)}")
    if not math.isfinite(result):
        raise ProtocolError(name, "must be a finite number", "not_finite")
    if lo is not None and result < lo:
        raise ProtocolError(name, f"must be at least {lo:g}, got {result:g}")
    if hi is not None and result > hi:
        raise ProtocolError(name, f"must be at most {hi:g}, got {result:g}")
    return result


def _optional_number(value: Any, name: str, **bounds: float) -> float | None:
    return None if value is None else number(value, name, **bounds)


def _integer(value: Any, name: str, *, lo: int | None = None) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise ProtocolError(name, f"must be an integer, got {_type_name(value)}")
    if lo is not None and value < lo:
        raise ProtocolError(name, f"must be at least {lo}, got {value}")
    return value


def text_problem(value: str) -> str | None:
    """Why PostgreSQL could not store this text (a NUL, an unpaired surrogate), or None."""
    if "\x00" in value:
        return "must not contain a NUL character"
    if not value.isascii():
        try:
            value.encode("utf-8")
        except UnicodeEncodeError:
            return "must not contain an unpaired surrogate"
    return None


def _string(value: Any, name: str, *, empty: bool = False, max_length: int = MAX_TEXT) -> str:
    if not isinstance(value, str):
        raise ProtocolError(name, f"must be a string, got {_type_name(value)}")
    if not empty and not value:
        raise ProtocolError(name, "must not be empty")
    if len(value) > max_length:
        raise ProtocolError(name, f"must be at most {max_length} characters", "too_long")
    if "\x00" in value or not value.isascii():  # the common case costs no call
        problem = text_problem(value)
        if problem is not None:
            raise ProtocolError(name, problem, "bad_text")
    return value


def json_tree(value: Any, name: str, depth: int = 0) -> Any:
    """A free-form JSON value (specs, a step's result, ...) checked whole for what storage
    refuses: bad text in keys or strings, non-finite numbers, nesting deeper than MAX_DEPTH."""
    if isinstance(value, str):
        return _string(value, name, empty=True)
    if isinstance(value, float) and not math.isfinite(value):
        raise ProtocolError(name, "must be a finite number", "not_finite")
    if isinstance(value, dict | list) and depth >= MAX_DEPTH:
        raise ProtocolError(name, f"nests deeper than {MAX_DEPTH} levels")
    if isinstance(value, dict):
        for key, item in value.items():
            _string(key, f"{name} key", empty=True, max_length=MAX_KEY)
            json_tree(item, f"{name}.{key}", depth + 1)
    elif isinstance(value, list):
        for i, item in enumerate(value):
            json_tree(item, f"{name}[{i}]", depth + 1)
    return value


def _json_object(value: Any, name: str) -> dict:
    return json_tree(_object(value, name), name)


def _optional_string(value: Any, name: str) -> str | None:
    return None if value is None else _string(value, name, empty=True)


def _boolean(value: Any, name: str) -> bool:
    """A boolean; the HTTP endpoint's "true"/"false"/"1"/"0" strings are accepted too."""
    if isinstance(value, bool):
        return value
    if isinstance(value, str) and value.strip().lower() in ("true", "1", "yes", "on"):
        return True
    if isinstance(value, str) and value.strip().lower() in ("false", "0", "no", "off", ""):
        return False
    if isinstance(value, int) and value in (0, 1):
        return bool(value)
    raise ProtocolError(name, f"must be true or false, got {value!r}")


def _choice(value: Any, name: str, choices: Iterable[str]) -> str:
    choices = tuple(choices)
    if value not in choices:
        raise ProtocolError(name, f"must be one of {', '.join(choices)}, got {value!r}")
    return value


def _request_id(value: Any, name: str = "request_id") -> str:
    if not isinstance(value, str) or not REQUEST_ID_RE.match(value):
        raise ProtocolError(name, "must be 32 lower-case hex characters")
    return value


def _identifier(value: Any, name: str) -> str:
    """A mission or assignment id: a non-empty string (ints are accepted and stringified)."""
    if isinstance(value, int) and not isinstance(value, bool):
        value = str(value)
    return _string(value, name, max_length=MAX_ID_LENGTH)


def timestamp(value: Any, name: str = "ts") -> float:
    """Seconds since the epoch, between 1970 and 2100 (MAX_TS)."""
    # Telemetry has one per object: a plain float takes the short way.
    result = value if type(value) is float else number(value, name)
    if not 0 <= result < MAX_TS:  # NaN fails this too
        raise ProtocolError(
            name, f"{result:g} is not a time between 1970 and 2100", "bad_timestamp"
        )
    return result


def _ts(obj: Mapping[str, Any], prefix: str = "") -> float:
    return timestamp(_require(obj, "ts", prefix), prefix + "ts")


def _drop_none(data: dict) -> dict:
    return {k: v for k, v in data.items() if v is not None}


# ---------------------------------------------------------------------------------------
# Shared value types.


@dataclass(frozen=True)
class Position:
    """WGS84 lat/lon in degrees; alt in metres above the home point."""

    lat: float
    lon: float
    alt: float

    def to_dict(self) -> dict:
        return {"lat": self.lat, "lon": self.lon, "alt": self.alt}


def latitude(value: Any, name: str = "lat") -> float:
    return number(value, name, lo=-90.0, hi=90.0)


def longitude(value: Any, name: str = "lon") -> float:
    return number(value, name, lo=-180.0, hi=180.0)


def parse_position(obj: Any, name: str = "position") -> Position:
    obj = _object(obj, name)
    return Position(
        lat=latitude(_require(obj, "lat", f"{name}."), f"{name}.lat"),
        lon=longitude(_require(obj, "lon", f"{name}."), f"{name}.lon"),
        alt=number(_require(obj, "alt", f"{name}."), f"{name}.alt"),
    )


def _optional_position(obj: Any, name: str = "position") -> Position | None:
    return None if obj is None else parse_position(obj, name)


def _position_dict(position: Position | None) -> dict | None:
    return None if position is None else position.to_dict()


# ---------------------------------------------------------------------------------------
# Commands and their parameters (control requests and mission steps share them).


def _no_params(params: dict, prefix: str) -> dict:
    return {}


def _force_param(params: dict, prefix: str) -> dict:
    return {"force": _boolean(params.get("force", False), prefix + "force")}


def _takeoff_params(params: dict, prefix: str) -> dict:
    altitude = params.get("altitude")
    if altitude is None:
        altitude = DEFAULT_TAKEOFF_ALTITUDE
    return {"altitude": number(altitude, prefix + "altitude", lo=0.5, hi=MAX_ALTITUDE)}


def _value_param(params: dict, prefix: str) -> dict:
    return {"value": number(_require(params, "value", prefix), prefix + "value")}


def _navigate_params(params: dict, prefix: str) -> dict:
    delta = params.get("altitude_delta")
    return {
        "lat": latitude(_require(params, "lat", prefix), prefix + "lat"),
        "lon": longitude(_require(params, "lon", prefix), prefix + "lon"),
        "altitude_delta": 0.0 if delta is None else number(delta, prefix + "altitude_delta"),
    }


def _objrequest_params(params: dict, prefix: str) -> dict:
    value = _string(_require(params, "value", prefix), prefix + "value")
    if not OBJECT_NAME_RE.match(value):
        raise ProtocolError(prefix + "value", f"{value!r} is not a flight-controller object name")
    return {"value": value}


def _tolerance_params(params: dict, prefix: str) -> dict:
    result = {}
    for name in ("horizontal_tolerance", "vertical_tolerance"):
        value = params.get(name)
        result[name] = (
            DEFAULT_TOLERANCE if value is None else number(value, prefix + name, lo=0.01, hi=1e4)
        )
    return result


def _sleep_params(params: dict, prefix: str) -> dict:
    return {"value": number(_require(params, "value", prefix), prefix + "value", lo=0, hi=86400)}


def _virtualalarm_params(params: dict, prefix: str) -> dict:
    return {
        "level": _choice(_require(params, "level", prefix), prefix + "level", ALARM_LEVELS),
        "message": _string(params.get("message", ""), prefix + "message", empty=True),
    }


def _sense_params(params: dict, prefix: str) -> dict:
    return {"sensor": _string(_require(params, "sensor", prefix), prefix + "sensor")}


_PARAMS: dict[str, Callable[[dict, str], dict]] = {
    "arm": _no_params,
    "disarm": _force_param,
    "takeoff": _takeoff_params,
    "land": _no_params,
    "changeN": _value_param,
    "changeE": _value_param,
    "altitude": _value_param,
    "navigate": _navigate_params,
    "takepic": _no_params,
    "objrequest": _objrequest_params,
    "resetfc": _force_param,
    "rebuildtelemetry": _no_params,
    "wait_for_flight": _tolerance_params,
    "sleep": _sleep_params,
    "virtualalarm": _virtualalarm_params,
    "sense": _sense_params,
}


_CONTROL_SET = frozenset(CONTROL_COMMANDS)
_STEP_SET = frozenset(STEP_COMMANDS)


def validate_command(
    command: Any, params: Any = None, *, mission: bool = False, prefix: str = ""
) -> dict:
    """Check a command and its params; return the params normalised (floats, defaults).

    `mission=True` also allows the mission-only commands (wait_for_flight, sleep, ...).
    Unknown extra params are dropped. Raises ProtocolError naming the bad field.
    """
    allowed = _STEP_SET if mission else _CONTROL_SET
    if not isinstance(command, str) or command not in allowed:
        where = "in a mission" if mission else "as a control command"
        raise ProtocolError(prefix + "command", f"unknown command {command!r} {where}")
    if params is None:
        params = {}
    elif not isinstance(params, dict):
        raise ProtocolError(prefix + "params", f"must be a JSON object, got {_type_name(params)}")
    try:
        result = _PARAMS[command](params, "params.")
        if mission and command in _STEP_EXTRAS:
            result.update(_STEP_EXTRAS[command](params, "params."))
        return result
    except ProtocolError as exc:
        if not prefix:
            raise
        raise ProtocolError(prefix + exc.field, exc.message) from None


# ---------------------------------------------------------------------------------------
# Control.


@dataclass(frozen=True)
class ControlRequest:
    request_id: str
    command: str
    params: dict
    ts: float = field(default_factory=now)

    def to_dict(self) -> dict:
        # Spelled out: dataclasses.asdict deep-copies, on every command's way out.
        return {
            "request_id": self.request_id,
            "command": self.command,
            "params": dict(self.params),
            "ts": self.ts,
        }


@dataclass(frozen=True)
class ControlResponse:
    request_id: str
    command: str
    ok: bool
    result: dict | None = None
    error: str | None = None
    ts: float = field(default_factory=now)

    def to_dict(self) -> dict:
        return {
            "request_id": self.request_id,
            "command": self.command,
            "ok": self.ok,
            "result": None if self.result is None else dict(self.result),
            "error": self.error,
            "ts": self.ts,
        }


def control_request(command: str, params: dict | None = None) -> ControlRequest:
    """A new, validated control request with a fresh request id (for the ground)."""
    return ControlRequest(new_request_id(), command, validate_command(command, params or {}))


def parse_control_request(obj: Any) -> ControlRequest:
    obj = _object(obj, "message")
    request_id = _request_id(_require(obj, "request_id"))
    command = _require(obj, "command")
    params = validate_command(command, obj.get("params"))
    ts = number(obj["ts"], "ts", lo=0) if obj.get("ts") is not None else now()
    return ControlRequest(request_id, command, params, ts)


def parse_control_response(obj: Any) -> ControlResponse:
    obj = _object(obj, "message")
    ok = _require(obj, "ok")
    if not isinstance(ok, bool):
        raise ProtocolError("ok", "must be true or false")
    result = obj.get("result")
    if result is not None:
        _json_object(result, "result")
    error = _optional_string(obj.get("error"), "error")
    if not ok and not error:
        raise ProtocolError("error", "a failed response must say why")
    return ControlResponse(
        request_id=_request_id(_require(obj, "request_id")),
        command=_string(_require(obj, "command"), "command"),
        ok=ok,
        result=result,
        error=error,
        ts=_ts(obj),
    )


# ---------------------------------------------------------------------------------------
# Missions.


@dataclass(frozen=True)
class Step:
    index: int
    command: str
    params: dict

    def to_dict(self) -> dict:
        return {"index": self.index, "command": self.command, "params": self.params}


@dataclass(frozen=True)
class MissionPayload:
    mission_id: str
    assignment_id: str
    steps: tuple[Step, ...]

    def to_dict(self) -> dict:
        return {
            "mission_id": self.mission_id,
            "assignment_id": self.assignment_id,
            "steps": [step.to_dict() for step in self.steps],
        }


@dataclass(frozen=True)
class MissionStart:
    request_id: str
    mission_id: str
    assignment_id: str
    payload: str  # base64, decoded by the mission worker (it times the decode)
    action: str = "start"

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class MissionStop:
    request_id: str
    mission_id: str
    action: str = "stop"

    def to_dict(self) -> dict:
        return asdict(self)


def parse_step(obj: Any, name: str = "step") -> Step:
    """One mission step; errors name the field under `name` (e.g. payload.steps[3].index)."""
    try:
        return _parse_step(obj)
    except ProtocolError as exc:
        # Field paths are built only on failure: a 5 000-step mission decodes ~2x faster.
        raise ProtocolError(f"{name}.{exc.field}" if exc.field else name, exc.message) from None


def _parse_step(obj: Any) -> Step:
    if not isinstance(obj, dict):
        raise ProtocolError("", f"must be a JSON object, got {_type_name(obj)}")
    index = _integer(_require(obj, "index"), "index", lo=0)
    command = _require(obj, "command")
    params = validate_command(command, obj.get("params"), mission=True)
    return Step(index, command, params)


def parse_mission_payload(obj: Any) -> MissionPayload:
    """The decoded JSON of a mission payload → MissionPayload (every step validated)."""
    obj = _object(obj, "payload")
    mission_id = _identifier(_require(obj, "mission_id", "payload."), "payload.mission_id")
    assignment_id = _identifier(_require(obj, "assignment_id", "payload."), "payload.assignment_id")
    raw_steps = _require(obj, "steps", "payload.")
    if not isinstance(raw_steps, list):
        raise ProtocolError("payload.steps", f"must be a list, got {_type_name(raw_steps)}")
    if not raw_steps:
        raise ProtocolError("payload.steps", "must hold at least one step")
    steps = []
    seen: set[int] = set()
    for position, raw in enumerate(raw_steps):
        step = parse_step(raw, f"payload.steps[{position}]")
        if step.index in seen:
            raise ProtocolError(
                f"payload.steps[{position}].index", f"index {step.index} appears twice"
            )
        seen.add(step.index)
        steps.append(step)
    return MissionPayload(mission_id, assignment_id, tuple(steps))


def encode_mission_payload(
    mission_id: str | int, assignment_id: str | int, steps: Iterable[Step | Mapping]
) -> str:
    """Validate and encode a mission payload: standard base64 of its UTF-8 JSON."""
    raw_steps = [s.to_dict() if isinstance(s, Step) else dict(s) for s in steps]
    payload = parse_mission_payload(
        {"mission_id": str(mission_id), "assignment_id": str(assignment_id), "steps": raw_steps}
    )
    text = json.dumps(payload.to_dict(), separators=(",", ":"), ensure_ascii=False)
    return base64.b64encode(text.encode("utf-8")).decode("ascii")


def decode_mission_payload(b64: Any) -> MissionPayload:
    """Standard base64 → UTF-8 JSON → validated MissionPayload, or ProtocolError."""
    if isinstance(b64, str):
        try:
            b64 = b64.encode("ascii")
        except UnicodeEncodeError:
            raise ProtocolError("payload", "base64 must be ASCII") from None
    if not isinstance(b64, bytes):
        raise ProtocolError("payload", f"must be a base64 string, got {_type_name(b64)}")
    try:
        raw = base64.b64decode(b64, validate=True)
    except (binascii.Error, ValueError) as exc:
        raise ProtocolError("payload", f"is not valid base64 ({exc})") from None
    try:
        data = json.loads(raw.decode("utf-8"))
    except UnicodeDecodeError:
        raise ProtocolError("payload", "is not UTF-8") from None
    except json.JSONDecodeError as exc:
        raise ProtocolError("payload", f"is not JSON ({exc.msg} at {exc.pos})") from None
    return parse_mission_payload(data)


def mission_start(
    mission_id: str | int, assignment_id: str | int, steps: Iterable[Step | Mapping]
) -> MissionStart:
    """A ready-to-send start message for the ground (payload encoded, fresh request id)."""
    return MissionStart(
        request_id=new_request_id(),
        mission_id=str(mission_id),
        assignment_id=str(assignment_id),
        payload=encode_mission_payload(mission_id, assignment_id, steps),
    )


def parse_mission_request(obj: Any) -> MissionStart | MissionStop:
    """A `<id>/mission/in` message. The start payload is checked later, when decoded."""
    obj = _object(obj, "message")
    request_id = _request_id(_require(obj, "request_id"))
    action = _choice(_require(obj, "action"), "action", MISSION_ACTIONS)
    mission_id = _identifier(_require(obj, "mission_id"), "mission_id")
    if action == "stop":
        return MissionStop(request_id, mission_id)
    assignment_id = _identifier(_require(obj, "assignment_id"), "assignment_id")
    payload = _string(_require(obj, "payload"), "payload", max_length=50_000_000)
    return MissionStart(request_id, mission_id, assignment_id, payload)


@dataclass(frozen=True)
class MissionProgress:
    mission_id: str
    assignment_id: str | None
    status: str
    decode_ms: float | None = None
    error: str | None = None
    ts: float = field(default_factory=now)
    request_id: str | None = None  # optional addition: the start/stop request answered
    type: str = "mission"

    def to_dict(self) -> dict:
        data = asdict(self)
        if self.request_id is None:
            del data["request_id"]
        return data


@dataclass(frozen=True)
class StepProgress:
    mission_id: str
    assignment_id: str | None
    index: int
    command: str
    status: str
    position: Position | None = None
    duration_s: float | None = None
    result: dict = field(default_factory=dict)
    error: str | None = None  # optional addition: why a step failed
    ts: float = field(default_factory=now)
    type: str = "step"

    def to_dict(self) -> dict:
        data = asdict(self)
        data["position"] = _position_dict(self.position)
        return data


def mission_reply(
    request: MissionStart | MissionStop,
    status: str,
    *,
    decode_ms: float | None = None,
    error: str | None = None,
) -> MissionProgress:
    """The mission progress that answers a start or stop request, naming the request."""
    assignment_id = request.assignment_id if isinstance(request, MissionStart) else None
    return MissionProgress(
        request.mission_id, assignment_id, status, decode_ms, error, request_id=request.request_id
    )


def step_progress(
    payload: MissionPayload,
    step: Step,
    status: str,
    position: Position | None,
    *,
    duration_s: float | None = None,
    result: dict | None = None,
    error: str | None = None,
) -> StepProgress:
    """The progress of one step of a running mission."""
    return StepProgress(
        payload.mission_id,
        payload.assignment_id,
        step.index,
        step.command,
        status,
        position,
        duration_s,
        result or {},
        error,
    )


def mission_end(
    payload: MissionPayload,
    status: str,
    *,
    error: str | None = None,
    request_id: str | None = None,
) -> MissionProgress:
    """A running mission's last word: `completed`, or `stopped` with why, naming the stop
    request when the ground asked for it."""
    return MissionProgress(
        payload.mission_id,
        payload.assignment_id,
        status,
        error=error,
        request_id=request_id if status == "stopped" else None,
    )


def mission_refusal(obj: Any, error: str) -> MissionProgress | None:
    """The `rejected` answer to a mission request that does not parse; None when it names
    no request id (nobody waits for an answer)."""
    request_id = request_id_of(obj)
    if request_id is None:
        return None
    mission_id = obj.get("mission_id")
    assignment_id = obj.get("assignment_id")
    return MissionProgress(
        mission_id if isinstance(mission_id, str) and mission_id else "unknown",
        assignment_id if isinstance(assignment_id, str) else None,
        "rejected",
        error=error,
        request_id=request_id,
    )


def parse_mission_progress(obj: Any) -> MissionProgress | StepProgress:
    """A `<id>/mission/out` message (mission status or step progress)."""
    obj = _object(obj, "message")
    kind = _choice(_require(obj, "type"), "type", ("mission", "step"))
    mission_id = _identifier(_require(obj, "mission_id"), "mission_id")
    assignment_id = obj.get("assignment_id")
    if assignment_id is not None:
        assignment_id = _identifier(assignment_id, "assignment_id")
    ts = _ts(obj)
    if kind == "mission":
        request_id = obj.get("request_id")
        return MissionProgress(
            mission_id=mission_id,
            assignment_id=assignment_id,
            status=_choice(_require(obj, "status"), "status", MISSION_STATUSES),
            decode_ms=_optional_number(obj.get("decode_ms"), "decode_ms", lo=0),
            error=_optional_string(obj.get("error"), "error"),
            ts=ts,
            request_id=None if request_id is None else _request_id(request_id),
        )
    result = obj.get("result")
    return StepProgress(
        mission_id=mission_id,
        assignment_id=assignment_id,
        index=_integer(_require(obj, "index"), "index", lo=0),
        command=_choice(_require(obj, "command"), "command", STEP_COMMANDS),
        status=_choice(_require(obj, "status"), "status", STEP_STATUSES),
        position=_optional_position(obj.get("position")),
        duration_s=_optional_number(obj.get("duration_s"), "duration_s", lo=0),
        result={} if result is None else _json_object(result, "result"),
        error=_optional_string(obj.get("error"), "error"),
        ts=ts,
    )


# ---------------------------------------------------------------------------------------
# Heartbeats and alarms.


@dataclass(frozen=True)
class MissionRef:
    mission_id: str
    assignment_id: str | None
    index: int | None

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class Heartbeat:
    drone_id: str
    ts: float
    position: Position | None
    battery_voltage: float | None
    battery_remaining: float | None
    armed: bool
    airborne: bool
    flight_mode: str
    mission: MissionRef | None
    fc_protocol: str
    fc_connected: bool
    type: str = "heartbeat"
    # (optional) what to change on the flight controller before it can fly (sentences).
    fc_setup: tuple[str, ...] = ()
    # (optional) the flight controller's wind estimate and the drone's limit (onboard/wind.py).
    wind: WindReport | None = None
    # (optional) the Remote ID broadcast's health, None when the drone knows nothing of it.
    remote_id: RemoteIdHealth | None = None
    # (optional) the battery's serial number as its flight controller reports it.
    battery_serial: str | None = None

    def to_dict(self) -> dict:
        return {
            "type": "heartbeat",
            "drone_id": self.drone_id,
            "ts": self.ts,
            "position": _position_dict(self.position),
            "battery": {
                "voltage": self.battery_voltage,
                "remaining": self.battery_remaining,
                **({} if self.battery_serial is None else {"serial": self.battery_serial}),
            },
            "armed": self.armed,
            "airborne": self.airborne,
            "flight_mode": self.flight_mode,
            "mission": None if self.mission is None else self.mission.to_dict(),
            "fc": {
                "protocol": self.fc_protocol,
                "connected": self.fc_connected,
                **({"setup": list(self.fc_setup)} if self.fc_setup else {}),
            },
            **({} if self.remote_id is None else {"remote_id": self.remote_id.to_dict()}),
            **({} if self.wind is None else {"wind": self.wind.to_dict()}),
        }


@dataclass(frozen=True)
class RemoteIdHealth:
    """What the Remote ID broadcast says (docs/remote-id.md): `ok` when it is good to arm
    (OPEN_DRONE_ID_ARM_STATUS 0, or a declared external module), else `error` says why."""

    ok: bool
    error: str = ""
    source: str = "odid"  # "odid": the module's own ARM_STATUS

    def to_dict(self) -> dict:
        return {"ok": self.ok, "error": self.error, "source": self.source}


# The most a wind figure may say (m/s): beyond any wind a drone reports and flies in.
MAX_WIND_FIGURE = 100.0
WIND_ACTIONS = ("return",)


@dataclass(frozen=True)
class WindReport:
    """The heartbeat's `wind`: the flight controller's estimate (the air's velocity, m/s
    North-East-Down, and its horizontal `speed`), the drone's `limit`, the message it came
    from, and `action` ("return", with `since`) once the wind made the drone return."""

    north: float
    east: float
    down: float
    speed: float
    limit: float
    source: str = ""
    action: str | None = None
    since: float | None = None

    def to_dict(self) -> dict:
        return _drop_none(asdict(self))


def _wind_report(obj: Any) -> WindReport | None:
    if obj is None:
        return None
    obj = _object(obj, "wind")
    bound = MAX_WIND_FIGURE

    def figure(key: str, lo: float) -> float:
        return number(_require(obj, key, "wind."), f"wind.{key}", lo=lo, hi=bound)

    action = obj.get("action")
    since = obj.get("since")
    return WindReport(
        north=figure("north", -bound),
        east=figure("east", -bound),
        down=figure("down", -bound),
        speed=figure("speed", 0.0),
        limit=figure("limit", 0.0),
        source=_string(obj.get("source") or "", "wind.source", empty=True, max_length=32),
        action=None if action is None else _choice(action, "wind.action", WIND_ACTIONS),
        since=None if since is None else timestamp(since, "wind.since"),
    )


def _remote_id_health(obj: Any) -> RemoteIdHealth | None:
    if obj is None:
        return None
    obj = _object(obj, "remote_id")
    return RemoteIdHealth(
        ok=_boolean(_require(obj, "ok", "remote_id."), "remote_id.ok"),
        error=_string(obj.get("error") or "", "remote_id.error", empty=True, max_length=200),
        source=_string(obj.get("source") or "odid", "remote_id.source", max_length=16),
    )


# SMART_BATTERY_INFO's serial_number is 16 characters, BATTERY_INFO's 32 [MAVLink common].
MAX_BATTERY_SERIAL = 32


def _battery_serial(value: Any) -> str | None:
    if value is None:
        return None
    return _string(value, "battery.serial", max_length=MAX_BATTERY_SERIAL).strip() or None


def _mission_ref(obj: Any, name: str = "mission") -> MissionRef | None:
    if obj is None:
        return None
    obj = _object(obj, name)
    assignment_id = obj.get("assignment_id")
    index = obj.get("index")
    return MissionRef(
        mission_id=_identifier(_require(obj, "mission_id", f"{name}."), f"{name}.mission_id"),
        assignment_id=None
        if assignment_id is None
        else _identifier(assignment_id, f"{name}.assignment_id"),
        index=None if index is None else _integer(index, f"{name}.index", lo=0),
    )


def parse_heartbeat(obj: Any) -> Heartbeat:
    obj = _object(obj, "message")
    _choice(_require(obj, "type"), "type", ("heartbeat",))
    drone_id = _require(obj, "drone_id")
    if not is_drone_id(drone_id):
        raise ProtocolError("drone_id", f"{drone_id!r} is not a valid drone id")
    battery = obj.get("battery") or {}
    battery = _object(battery, "battery")
    fc = _object(obj.get("fc") or {}, "fc")
    return _checked(
        Heartbeat,
        drone_id=drone_id,
        ts=_ts(obj),
        position=_optional_position(obj.get("position")),
        battery_voltage=_optional_number(battery.get("voltage"), "battery.voltage", lo=0),
        battery_remaining=_optional_number(
            battery.get("remaining"), "battery.remaining", lo=0, hi=1
        ),
        armed=_boolean(obj.get("armed", False), "armed"),
        airborne=_boolean(obj.get("airborne", False), "airborne"),
        flight_mode=_string(obj.get("flight_mode") or "UNKNOWN", "flight_mode"),
        mission=_mission_ref(obj.get("mission")),
        fc_protocol=_string(fc.get("protocol") or "unknown", "fc.protocol"),
        fc_connected=_boolean(fc.get("connected", False), "fc.connected"),
        fc_setup=_setup_list(fc.get("setup")),
        wind=_wind_report(obj.get("wind")),
        remote_id=_remote_id_health(obj.get("remote_id")),
        battery_serial=_battery_serial(battery.get("serial")),
        type="heartbeat",
    )


T = TypeVar("T")


def _checked(cls: type[T], **fields: Any) -> T:
    """A frozen dataclass from fields already checked, every field given: the same object
    its constructor builds, without a `__setattr__` call per field (a fifth of a
    heartbeat's parse, which the ground does for every drone every 5 s)."""
    instance = object.__new__(cls)
    instance.__dict__.update(fields)
    return instance


def _setup_list(value: Any) -> tuple[str, ...]:
    if value is None:
        return ()
    if not isinstance(value, list) or len(value) > 64:
        raise ProtocolError("fc.setup", "must be a list of at most 64 sentences")
    return tuple(_string(item, f"fc.setup[{i}]") for i, item in enumerate(value))


@dataclass(frozen=True)
class Alarm:
    level: str
    message: str
    position: Position | None = None
    mission_id: str | None = None
    assignment_id: str | None = None
    index: int | None = None
    sensor: str | None = None
    value: float | None = None
    ts: float = field(default_factory=now)
    type: str = "alarm"

    def to_dict(self) -> dict:
        data = asdict(self)
        data["position"] = _position_dict(self.position)
        return data


def parse_alarm(obj: Any) -> Alarm:
    obj = _object(obj, "message")
    _choice(_require(obj, "type"), "type", ("alarm",))
    mission_id = obj.get("mission_id")
    assignment_id = obj.get("assignment_id")
    index = obj.get("index")
    return Alarm(
        level=_choice(_require(obj, "level"), "level", ALARM_LEVELS),
        message=_string(obj.get("message") or "", "message", empty=True),
        position=_optional_position(obj.get("position")),
        mission_id=None if mission_id is None else _identifier(mission_id, "mission_id"),
        assignment_id=None
        if assignment_id is None
        else _identifier(assignment_id, "assignment_id"),
        index=None if index is None else _integer(index, "index", lo=0),
        sensor=_optional_string(obj.get("sensor"), "sensor"),
        value=_optional_number(obj.get("value"), "value"),
        ts=_ts(obj),
    )


# ---------------------------------------------------------------------------------------
# Gear.


@dataclass(frozen=True)
class GearQuery:
    request_id: str
    query: str
    sensor: str | None = None

    def to_dict(self) -> dict:
        return _drop_none(asdict(self))


@dataclass(frozen=True)
class GearReply:
    request_id: str
    ok: bool
    specs: dict | None = None
    sensors: dict | None = None
    reading: dict | None = None
    error: str | None = None
    ts: float = field(default_factory=now)

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class GearAnnouncement:
    specs: dict
    sensors: dict
    ts: float = field(default_factory=now)
    type: str = "gear"

    def to_dict(self) -> dict:
        return asdict(self)


def parse_gear_query(obj: Any) -> GearQuery:
    obj = _object(obj, "message")
    request_id = _request_id(_require(obj, "request_id"))
    query = _choice(_require(obj, "query"), "query", GEAR_QUERIES)
    sensor = obj.get("sensor")
    if query == "reading":
        sensor = _string(_require(obj, "sensor"), "sensor")
    elif sensor is not None:
        sensor = _string(sensor, "sensor")
    return GearQuery(request_id, query, sensor)


def parse_gear_message(obj: Any) -> GearReply | GearAnnouncement:
    """A `<id>/gear/out` message: a reply (has request_id) or an announcement."""
    obj = _object(obj, "message")
    if obj.get("request_id") is None:
        _choice(_require(obj, "type"), "type", ("gear",))
        return GearAnnouncement(
            specs=_json_object(_require(obj, "specs"), "specs"),
            sensors=_json_object(_require(obj, "sensors"), "sensors"),
            ts=_ts(obj),
        )
    ok = _require(obj, "ok")
    if not isinstance(ok, bool):
        raise ProtocolError("ok", "must be true or false")
    parts = {}
    for name in ("specs", "sensors", "reading"):
        value = obj.get(name)
        parts[name] = None if value is None else _json_object(value, name)
    return GearReply(
        request_id=_request_id(obj["request_id"]),
        ok=ok,
        error=_optional_string(obj.get("error"), "error"),
        ts=_ts(obj),
        **parts,
    )


# ---------------------------------------------------------------------------------------
# Telemetry, pictures and camera frames.


@dataclass(frozen=True)
class TelemetryObject:
    name: str
    ts: float
    fields: dict

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class Telemetry:
    objects: tuple[TelemetryObject, ...]
    ts: float = field(default_factory=now)

    def to_dict(self) -> dict:
        return {"ts": self.ts, "objects": [o.to_dict() for o in self.objects]}


def parse_telemetry(obj: Any) -> Telemetry:
    obj = _object(obj, "message")
    raw = _require(obj, "objects")
    if not isinstance(raw, list):
        raise ProtocolError("objects", "must be a list")
    objects = []
    for i, item in enumerate(raw):
        name = f"objects[{i}]"
        item = _object(item, name)
        objects.append(
            TelemetryObject(
                name=_string(_require(item, "name", f"{name}."), f"{name}.name", max_length=64),
                ts=_ts(item, f"{name}."),
                fields=_object(_require(item, "fields", f"{name}."), f"{name}.fields"),
            )
        )
    return Telemetry(tuple(objects), _ts(obj))


def _jpeg(value: Any, name: str = "jpeg") -> bytes:
    value = _string(value, name, max_length=50_000_000)
    try:
        data = base64.b64decode(value, validate=True)
    except (binascii.Error, ValueError):
        raise ProtocolError(name, "is not valid base64") from None
    if not data.startswith(b"\xff\xd8"):
        raise ProtocolError(name, "is not a JPEG image")
    return data


@dataclass(frozen=True)
class Picture:
    name: str
    position: Position | None
    attitude: dict | None
    mission_id: str | None
    index: int | None
    jpeg: bytes
    ts: float = field(default_factory=now)
    assignment_id: str | None = None  # optional addition

    def to_dict(self) -> dict:
        return {
            "ts": self.ts,
            "name": self.name,
            "position": _position_dict(self.position),
            "attitude": self.attitude,
            "mission_id": self.mission_id,
            "assignment_id": self.assignment_id,
            "index": self.index,
            "jpeg": base64.b64encode(self.jpeg).decode("ascii"),
        }


def parse_picture(obj: Any) -> Picture:
    obj = _object(obj, "message")
    attitude = obj.get("attitude")
    if attitude is not None:
        attitude = _object(attitude, "attitude")
        attitude = {
            axis: _optional_number(attitude.get(axis), f"attitude.{axis}")
            for axis in ("roll", "pitch", "yaw")
        }
    mission_id = obj.get("mission_id")
    assignment_id = obj.get("assignment_id")
    index = obj.get("index")
    return Picture(
        name=_string(_require(obj, "name"), "name", max_length=255),
        position=_optional_position(obj.get("position")),
        attitude=attitude,
        mission_id=None if mission_id is None else _identifier(mission_id, "mission_id"),
        index=None if index is None else _integer(index, "index", lo=0),
        jpeg=_jpeg(_require(obj, "jpeg")),
        ts=_ts(obj),
        assignment_id=None
        if assignment_id is None
        else _identifier(assignment_id, "assignment_id"),
    )


@dataclass(frozen=True)
class CameraFrame:
    position: tuple[float, float, float]  # NED metres from home
    orientation: tuple[float, float, float, float]  # qx, qy, qz, qw
    jpeg: bytes
    ts: float = field(default_factory=now)

    def to_dict(self) -> dict:
        return {
            "ts": self.ts,
            "pose": {"position": list(self.position), "orientation": list(self.orientation)},
            "jpeg": base64.b64encode(self.jpeg).decode("ascii"),
        }


def _vector(value: Any, name: str, size: int) -> tuple[float, ...]:
    if not isinstance(value, list) or len(value) != size:
        raise ProtocolError(name, f"must be a list of {size} numbers")
    return tuple(number(v, f"{name}[{i}]") for i, v in enumerate(value))


def parse_camera_frame(obj: Any) -> CameraFrame:
    obj = _object(obj, "message")
    pose = _object(_require(obj, "pose"), "pose")
    return CameraFrame(
        position=_vector(_require(pose, "position", "pose."), "pose.position", 3),  # type: ignore[arg-type]
        orientation=_vector(_require(pose, "orientation", "pose."), "pose.orientation", 4),  # type: ignore[arg-type]
        jpeg=_jpeg(_require(obj, "jpeg")),
        ts=_ts(obj),
    )


# ---------------------------------------------------------------------------------------
# Bytes on the wire.


def encode(message: Any) -> bytes:
    """A message dataclass (or plain dict) → compact UTF-8 JSON bytes."""
    data = message.to_dict() if hasattr(message, "to_dict") else message
    return json.dumps(data, separators=(",", ":"), ensure_ascii=False).encode("utf-8")


def decode_json(payload: bytes | str) -> Any:
    """UTF-8 JSON bytes → Python value, or ProtocolError("message", ...)."""
    try:
        text = payload.decode("utf-8") if isinstance(payload, bytes | bytearray) else payload
        return json.loads(text)
    except UnicodeDecodeError:
        raise ProtocolError("message", "is not UTF-8") from None
    except json.JSONDecodeError as exc:
        raise ProtocolError("message", f"is not JSON ({exc.msg} at {exc.pos})") from None


def request_id_of(obj: Any) -> str | None:
    """The request id of a (possibly malformed) message, when it has a valid one."""
    if isinstance(obj, dict):
        value = obj.get("request_id")
        if isinstance(value, str) and REQUEST_ID_RE.match(value):
            return value
    return None


# Parser per (channel, direction) of a topic, for the gateway and the agent.
PARSERS: dict[tuple[str, str], Callable[[Any], Any]] = {
    ("control", "in"): parse_control_request,
    ("mission", "in"): parse_mission_request,
    ("gear", "in"): parse_gear_query,
    ("control", "out"): parse_control_response,
    ("mission", "out"): parse_mission_progress,
    ("gear", "out"): parse_gear_message,
    ("heartbeats", "out"): parse_heartbeat,
    ("alarms", "out"): parse_alarm,
    ("telemetry", "out"): parse_telemetry,
    ("pictures", "out"): parse_picture,
    ("camera", "out"): parse_camera_frame,
}


def parse_message(topic_name: str, payload: bytes | str) -> tuple[str, str, Any]:
    """Raw MQTT topic + payload → (drone id, channel, parsed message), or ProtocolError."""
    drone_id, channel, direction = split_topic(topic_name)
    return drone_id, channel, PARSERS[(channel, direction)](decode_json(payload))


# ---------------------------------------------------------------------------------------
# Optional additions (docs/protocol.md marks each *(optional)*).

# The ground acknowledges an alarm on `<id>/alarms/in`; a drone repeats its CRITICAL alarm
# until it is acknowledged. A drone that does not know the channel simply never gets one.
IN_CHANNELS = (*IN_CHANNELS, "alarms")


@dataclass(frozen=True)
class AlarmAck:
    level: str
    ts: float = field(default_factory=now)
    type: str = "alarm_ack"

    def to_dict(self) -> dict:
        return asdict(self)


def parse_alarm_ack(obj: Any) -> AlarmAck:
    obj = _object(obj, "message")
    return AlarmAck(_choice(_require(obj, "level"), "level", ALARM_LEVELS), _ts(obj))


PARSERS[("alarms", "in")] = parse_alarm_ack


# A stop request's optional `then`: what the drone does once the mission has stopped.
# `hold` (the default) hovers where it is until the operator decides; `return` flies home,
# lands and disarms (a released panic call); `land` lands where it is.
STOP_FOLLOW_UPS = ("hold", "return", "land")


def stop_follow_up(obj: Any) -> str:
    value = obj.get("then") if isinstance(obj, dict) else None
    return "hold" if value is None else _choice(value, "then", STOP_FOLLOW_UPS)


def issued_at(obj: Any) -> float | None:
    """A request's optional `ts` (when the ground issued it, the ground's clock), or None."""
    value = obj.get("ts") if isinstance(obj, dict) else None
    return None if value is None else number(value, "ts", lo=0)


# Flight envelope (optional): `<id>/envelope/in`, the limits and geofence the drone enforces.


# The identity a drone broadcasts (Remote ID), carried by the envelope message (optional).
SERIAL_NUMBER_RE = re.compile(r"^[0-9A-HJ-NP-Z]{6,20}$")  # ANSI/CTA-2063-A's characters
OPERATOR_ID_RE = re.compile(r"^[0-9A-Za-z-]{1,20}$")


@dataclass(frozen=True)
class RemoteIdentity:
    """What the drone's Remote ID broadcasts: its serial number (ANSI/CTA-2063-A), the
    operator's registration number, the UA type (MAV_ODID_UA_TYPE), a Self ID text, the
    operator's position ([lat, lon]; None: the take-off point) and, in the EU, the
    operation's category (MAV_ODID_CATEGORY_EU) and the aircraft's class mark
    (MAV_ODID_CLASS_EU); 0 is undeclared, and an undeclared one is left off the wire."""

    serial_number: str
    operator_id: str = ""
    ua_type: int = 2  # MAV_ODID_UA_TYPE_HELICOPTER_OR_MULTIROTOR
    description: str = ""
    operator_location: tuple[float, float] | None = None
    eu_category: int = 0
    eu_class: int = 0

    def to_dict(self) -> dict:
        out: dict[str, Any] = {
            "serial_number": self.serial_number,
            "operator_id": self.operator_id,
            "ua_type": self.ua_type,
            "description": self.description,
            "operator_location": None
            if self.operator_location is None
            else list(self.operator_location),
        }
        if self.eu_category:
            out["eu_category"] = self.eu_category
        if self.eu_class:
            out["eu_class"] = self.eu_class
        return out


# MAV_ODID_CATEGORY_EU (undeclared, open, specific, certified) and MAV_ODID_CLASS_EU
# (undeclared, then class marks C0 to C6).
EU_CATEGORY_MAX = 3
EU_CLASS_MAX = 7


def parse_remote_identity(obj: Any, name: str = "remote_id") -> RemoteIdentity:
    obj = _object(obj, name)
    serial = _string(_require(obj, "serial_number", f"{name}."), f"{name}.serial_number")
    if not SERIAL_NUMBER_RE.match(serial):
        raise ProtocolError(f"{name}.serial_number", "is not an ANSI/CTA-2063-A serial number")
    operator = _string(obj.get("operator_id") or "", f"{name}.operator_id", empty=True)
    if operator and not OPERATOR_ID_RE.match(operator):
        raise ProtocolError(f"{name}.operator_id", "must be 1 to 20 letters, digits or -")
    ua_type = _integer(obj.get("ua_type", 2), f"{name}.ua_type", lo=0)
    if ua_type > 15:
        raise ProtocolError(f"{name}.ua_type", "must be a MAV_ODID_UA_TYPE (0 to 15)")
    eu_category = _integer(obj.get("eu_category", 0), f"{name}.eu_category", lo=0)
    if eu_category > EU_CATEGORY_MAX:
        raise ProtocolError(f"{name}.eu_category", "must be a MAV_ODID_CATEGORY_EU (0 to 3)")
    eu_class = _integer(obj.get("eu_class", 0), f"{name}.eu_class", lo=0)
    if eu_class > EU_CLASS_MAX:
        raise ProtocolError(f"{name}.eu_class", "must be a MAV_ODID_CLASS_EU (0 to 7)")
    # ASTM F3411's Self ID description is 23 characters.
    description = _string(
        obj.get("description") or "", f"{name}.description", empty=True, max_length=23
    )
    location = obj.get("operator_location")
    if location is not None:
        if not isinstance(location, list) or len(location) != 2:
            raise ProtocolError(f"{name}.operator_location", "must be [lat, lon]")
        location = (
            latitude(location[0], f"{name}.operator_location[0]"),
            longitude(location[1], f"{name}.operator_location[1]"),
        )
    return RemoteIdentity(serial, operator, ua_type, description, location, eu_category, eu_class)


@dataclass(frozen=True)
class EnvelopeUpdate:
    envelope: dict
    ts: float = field(default_factory=now)
    type: str = "envelope"
    # (optional) the Remote ID identity the drone broadcasts.
    remote_id: RemoteIdentity | None = None
    # (optional) when the drone uploads its logs after landing (onboard/collect.py MODES).
    log_collection: str | None = None

    def to_dict(self) -> dict:
        return {
            "type": "envelope",
            "ts": self.ts,
            "envelope": self.envelope,
            **({} if self.remote_id is None else {"remote_id": self.remote_id.to_dict()}),
            **({} if self.log_collection is None else {"log_collection": self.log_collection}),
        }


def parse_envelope_update(obj: Any) -> EnvelopeUpdate:
    """An envelope message; the envelope itself is checked by onboard.envelope.parse_envelope."""
    from .envelope import EnvelopeError, parse_envelope

    obj = _object(obj, "message")
    body = _object(_require(obj, "envelope"), "envelope")
    try:
        parsed = parse_envelope(body)
    except EnvelopeError as exc:
        raise ProtocolError(f"envelope.{exc.field}", exc.message) from None
    identity = obj.get("remote_id")
    return EnvelopeUpdate(
        parsed.to_dict(),
        _ts(obj),
        remote_id=None if identity is None else parse_remote_identity(identity),
        log_collection=_log_collection(obj.get("log_collection")),
    )


def _log_collection(value: Any) -> str | None:
    """The envelope message's optional log collection mode; an unknown one is ignored (the
    drone keeps the mode it had) so a newer ground's mode never costs the envelope itself."""
    from .collect import MODES

    if value is None:
        return None
    if value not in MODES:
        logging.getLogger(__name__).warning("ignoring the log collection mode %r", value)
        return None
    return str(value)


PARSERS[("envelope", "in")] = parse_envelope_update


# Mission pause and resume (optional): `action: pause` holds the drone where it is and
# keeps the mission's place; `action: resume` carries on from the step it was on. The drone
# answers each with a mission progress of status `paused` or `resumed` (or `rejected`, with
# the reason, when there is nothing to pause or resume).
PAUSE_ACTIONS = ("pause", "resume")
MISSION_ACTIONS = (*MISSION_ACTIONS, *PAUSE_ACTIONS)
MISSION_STATUSES = (*MISSION_STATUSES, "paused", "resumed")


@dataclass(frozen=True)
class MissionPause:
    request_id: str
    mission_id: str
    action: str  # "pause" or "resume"

    def to_dict(self) -> dict:
        return asdict(self)


def mission_pause(mission_id: str | int, action: str) -> MissionPause:
    """A ready-to-send pause or resume request for the ground (fresh request id)."""
    return MissionPause(new_request_id(), str(mission_id), _choice(action, "action", PAUSE_ACTIONS))


_parse_start_or_stop = parse_mission_request


def parse_mission_request(obj: Any) -> MissionStart | MissionStop | MissionPause:  # noqa: F811
    """A `<id>/mission/in` message, pause and resume included."""
    obj = _object(obj, "message")
    if obj.get("action") not in PAUSE_ACTIONS:
        return _parse_start_or_stop(obj)
    return MissionPause(
        _request_id(_require(obj, "request_id")),
        _identifier(_require(obj, "mission_id"), "mission_id"),
        obj["action"],
    )


PARSERS[("mission", "in")] = parse_mission_request


# Operator controls (optional): `hold` hovers where the drone is (pausing a running
# mission, which `resume` carries on) and `return` flies home at the current altitude,
# lands and disarms. Neither is a mission step.
OPERATOR_COMMANDS = ("hold", "return")
CONTROL_COMMANDS = (*CONTROL_COMMANDS, *OPERATOR_COMMANDS)
_CONTROL_SET = frozenset(CONTROL_COMMANDS)
_PARAMS.update({command: _no_params for command in OPERATOR_COMMANDS})


# Optional step params (docs/protocol.md "Mission"): a mission leg's speed, the point the
# drone faces while flying it, and pictures by distance while it flies. Only mission steps
# carry them; a drone whose flight controller cannot do one refuses the whole mission.
MAX_SPEED = 50.0  # m/s


def _navigate_extras(params: dict, prefix: str) -> dict:
    extras: dict = {}
    if params.get("speed") is not None:
        extras["speed"] = number(params["speed"], prefix + "speed", lo=0.1, hi=MAX_SPEED)
    roi = params.get("roi")
    if roi is not None:
        if not isinstance(roi, list | tuple) or len(roi) != 2:
            raise ProtocolError(prefix + "roi", "must be [lat, lon]")
        extras["roi"] = [latitude(roi[0], prefix + "roi[0]"), longitude(roi[1], prefix + "roi[1]")]
    return extras


def _wait_extras(params: dict, prefix: str) -> dict:
    distance = params.get("photo_distance")
    if distance is None:
        return {}
    return {"photo_distance": number(distance, prefix + "photo_distance", lo=0.1, hi=1e4)}


_STEP_EXTRAS: dict[str, Callable[[dict, str], dict]] = {
    "navigate": _navigate_extras,
    "wait_for_flight": _wait_extras,
}


# The ground relays the other airborne drones nearby on `<id>/traffic/in` (optional:
# onboard/traffic.py, docs/protocol.md "Traffic"). QoS 0: a fresh picture comes with every
# live-separation pass, so a lost one is replaced rather than redelivered late.
IN_CHANNELS = (*IN_CHANNELS, "traffic")
QOS["traffic"] = 0


def _parse_traffic(obj: Any) -> Any:
    from .traffic import TrafficError, parse_traffic

    try:
        return parse_traffic(obj)
    except TrafficError as exc:
        raise ProtocolError("traffic", str(exc)) from exc


PARSERS[("traffic", "in")] = _parse_traffic
