"""The Drone Manager: commands with real replies, the REST command set of [Paula 2018], table 4.2.

A command is checked here before anything is sent (who may, which drone, which
parameters, is it safe), logged with its sender, sent over the web process's own broker connection
(workers.direct; through a gateway and the outbox, workers.outbox, when it is down)
and answered with the drone's own reply, correlated by a fresh request id.
"""

from __future__ import annotations

import asyncio
import contextvars
import logging
from collections.abc import Callable, Coroutine
from dataclasses import dataclass, field
from datetime import UTC, datetime
from functools import partial
from typing import Any

from asgiref.sync import sync_to_async
from django.conf import settings
from django.contrib.auth import get_user_model
from django.db import DatabaseError
from django.db.models import F, QuerySet
from django.utils import timezone
from django.utils.module_loading import import_string

from onboard import protocol
from workers import direct, outbox

from . import airworthiness, compiled, envelopes, tenancy, wind
from .models import ROLE_RANK, CommandLog, Drone, Role

log = logging.getLogger(__name__)

# The command set: queries answered by the Drone Identifier (GET) ...
QUERY_COMMANDS = ("discover", "getgear")
GET_COMMANDS = ("discover", "getgear", "objrequest")
# ... of which these ask the drone itself (a command sent), not the database.
DRONE_GET_COMMANDS = tuple(c for c in GET_COMMANDS if c not in QUERY_COMMANDS)
# ... and the Mission Planner's two (POST), routed to the hooks in settings.
CHAIN_COMMANDS = ("startchain", "stopchain")
ALL_COMMANDS = (*QUERY_COMMANDS, *protocol.CONTROL_COMMANDS, *CHAIN_COMMANDS)
POST_COMMANDS = tuple(c for c in ALL_COMMANDS if c not in GET_COMMANDS)
# What `POST /api/v1/drones/{id}/commands/` takes (the queries are GET resources there).
API_COMMANDS = (*protocol.CONTROL_COMMANDS, *CHAIN_COMMANDS)
# Refused while airborne unless forced: they would drop the drone (docs/protocol.md "Control").
UNSAFE_IN_FLIGHT = ("disarm", "resetfc")
# Whose answers the landing queue hears (settings.AIRSPACE_RETURN_ANSWERED): a `return`
# (or the hold sent for it) and an operator's `hold`, which takes a drone out of the queue.
HOME_COMMANDS = ("return", "hold")


class CommandRefused(Exception):
    """A command refused before sending; `status` is the HTTP status that says why."""

    def __init__(
        self,
        status: int,
        message: str,
        field: str | None = None,
        code: str | None = None,
        reasons: list[str] | None = None,
    ) -> None:
        super().__init__(message)
        self.status = status
        self.message = message
        self.field = field
        self.code = code
        # Each reason a `not_airworthy` refusal names, answered as the body's `reasons`.
        self.reasons = reasons


@dataclass
class Prepared:
    drone: Drone
    command: str
    params: dict
    entry: CommandLog
    # Where the move's terrain clearance could not be checked (fleet.envelopes.check_command).
    terrain_warnings: list[dict] = field(default_factory=list)
    # What the operator asked for, when the ground sends something else in its place
    # (a `return` into a landing queue: its hold), and what the reply adds to its result.
    asked: str = ""
    result_extra: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Outcome:
    """The drone's answer (None on timeout) to one command."""

    request_id: str
    command: str
    reply: dict | None

    @property
    def timed_out(self) -> bool:
        return self.reply is None

    @property
    def ok(self) -> bool:
        return bool(self.reply and self.reply.get("ok"))


def handle_control_reply(drone_id: str, response: protocol.ControlResponse) -> str | None:
    """Gateway handler for `<id>/control/out`."""
    return outbox.deliver_reply(drone_id, response.request_id, response.to_dict())


def rule_reads(command: str, at: datetime | None = None) -> dict:
    """What the rules `checked` asks for `command` read from the database, as annotations
    of the drone's lookup: airworthiness for an arm, the checklist gate (as at `at`, now)
    for an arm or a take-off. Each rule answers from them when they settle it and reads
    for itself when they leave it in doubt, so a command that may go is checked in one
    statement."""
    reads: dict = {}
    if command == "arm":
        reads |= airworthiness.lookup_reads()
    if command in CHECKLIST_COMMANDS:
        reads |= import_string(settings.FLIGHT_CHECKLIST_LOOKUP)(at)
    return reads


# Commands the checklist gate may stop (a take-off only when it arms: `checked`).
CHECKLIST_COMMANDS = ("arm", "takeoff")
# What a drone lookup is compiled with in place of the caller's values (fleet.compiled):
# values no caller has.
_STAND_INS = {
    "user": -(2**31) + 7,
    "bound": -(2**31) + 11,
    "drone_id": "\x00stand-in drone id",
    "at": datetime(1901, 2, 3, 4, 5, 6, 789012, tzinfo=UTC),
}


def _lookup(user: Any, drone_id: str, reads: dict) -> QuerySet:
    return (
        Drone.objects.for_user(user)
        .select_related("organisation")
        .annotate(member_role=F("organisation__memberships__role"), **reads)
        .filter(drone_id=drone_id)
    )


def _compile_lookup(shape: tuple[str, bool]) -> compiled.Compiled:
    """The lookup of `find_drone` for a command of the shape's reads, by a user bound to one
    organisation (a token made for it) or not."""
    reads_of, bound = shape
    stand_in_user = get_user_model()(pk=_STAND_INS["user"])
    stand_ins = {name: _STAND_INS[name] for name in ("user", "drone_id")}
    if bound:
        tenancy.bind(stand_in_user, _STAND_INS["bound"])
        stand_ins["bound"] = _STAND_INS["bound"]
    # The time the rules' reads are as at, when they read one (the checklist gate's).
    stand_ins["at"] = _STAND_INS["at"]
    reads = rule_reads(reads_of, _STAND_INS["at"])
    queryset = _lookup(stand_in_user, _STAND_INS["drone_id"], reads)[:1]
    return compiled.Compiled(queryset, stand_ins, optional=("at",))


_LOOKUPS = compiled.Shapes(_compile_lookup)


def _reads_of(command: str) -> str:
    """The command whose reads a lookup for `command` carries ("": none)."""
    return command if command in CHECKLIST_COMMANDS else ""


def find_drone(user: Any, drone_id: str, command: str = "") -> Drone:
    """The user's drone, or 404 (another organisation's drone is as unknown as none).

    The user's role in the drone's organisation comes with it (`drone.member_role`), in
    the same query, and so do the reads of the rules `command` is checked against
    (`rule_reads`): this is on every command's path, its SQL built once (fleet.compiled).
    """
    if not isinstance(drone_id, str) or not protocol.is_drone_id(drone_id):
        raise CommandRefused(404, f"Unknown drone {drone_id!r}.", "droneID")
    drone = None
    if user.is_authenticated:
        bound = getattr(user, tenancy.BOUND_ATTR, None)
        lookup = _LOOKUPS[(_reads_of(command), bound is not None)]
        values = {"user": user.pk, "drone_id": drone_id, "bound": bound, "at": timezone.now()}
        drone = lookup.first(**{name: values[name] for name in lookup.slots})
    if drone is None:
        raise CommandRefused(404, f"Unknown drone {drone_id!r}.", "droneID")
    return drone


def _may_operate(drone: Drone) -> bool:
    return ROLE_RANK[Role(drone.member_role)] >= ROLE_RANK[Role.OPERATOR]  # type: ignore[attr-defined]


def _refuse(entry_fields: dict, refusal: CommandRefused) -> CommandRefused:
    CommandLog.objects.create(
        **entry_fields,
        request_id="",
        outcome=CommandLog.Outcome.REJECTED,
        error=refusal.message,
        answered_at=timezone.now(),
    )
    return refusal


def prepare(
    user: Any, drone_id: str, command: str, params: dict | None, confirmed: bool = False
) -> Prepared:
    """Every check in order: drone (404), role (403), params (400), state and envelope (409).

    A move beyond the envelope's defaults needs `confirmed` (409 confirmation_required).
    Returns the pending log entry (not saved yet) with a fresh request id; refusals are
    logged here.
    """
    drone = find_drone(user, drone_id, command)
    try:
        return checked(user, drone, command, params, confirmed)
    except CommandRefused as refusal:
        base = {"drone": drone, "user": user, "command": str(command)[:40]}
        raise _refuse({**base, "params": params or {}}, refusal) from None


def checked(
    user: Any, drone: Drone, command: str, params: dict | None, confirmed: bool = False
) -> Prepared:
    """The checks after the drone is found (it carries `member_role`): role (403), params
    (400), state and envelope (409). Raises CommandRefused; logs nothing."""
    if not _may_operate(drone):
        raise CommandRefused(403, "Only operators and admins may command drones.")
    try:
        clean = protocol.validate_command(command, params or {})
    except protocol.ProtocolError as exc:
        field = exc.field.removeprefix("params.")
        raise CommandRefused(400, f"{field}: {exc.message}", field) from None
    if not drone.online:
        raise CommandRefused(409, f"Drone {drone.drone_id} is offline.")
    too_windy = wind.refusal(drone) if command in wind.TAKE_OFF_COMMANDS else None
    if too_windy is not None:
        raise CommandRefused(409, too_windy, code=wind.CODE)
    if command == "arm":
        unfit = airworthiness.refused(drone)
        if unfit is not None:
            raise CommandRefused(409, unfit[0], code="not_airworthy", reasons=unfit[1])
    if command == "arm" or (command == "takeoff" and not drone.armed):
        not_checked = import_string(settings.FLIGHT_CHECKLIST_GATE)(drone)
        if not_checked is not None:
            raise CommandRefused(409, not_checked, code="checklist_required")
    if command in UNSAFE_IN_FLIGHT and drone.airborne and not clean.get("force"):
        raise CommandRefused(
            409, f"Refusing {command} while {drone.drone_id} is airborne; send force=true."
        )
    asked, extra = command, {}
    try:
        if command == "return":
            # Home through the landing queue of the airspace app (named in settings): a
            # drone whose landing site is busy is sent to hold over home instead.
            routed = import_string(settings.AIRSPACE_RETURN_ROUTE)(drone)
            if routed is not None:
                command, clean, queue = routed
                extra, confirmed = {"queue": queue}, True
        unchecked = envelopes.check_command(drone, command, clean, confirmed)
    except envelopes.EnvelopeRefusal as exc:
        raise CommandRefused(409, exc.message, code=exc.code) from None
    # Written by `execute` (refusals are written by `prepare` at once).
    entry = CommandLog(
        drone=drone, user=user, request_id=protocol.new_request_id(), command=command, params=clean
    )
    return Prepared(
        drone, command, clean, entry, terrain_warnings=unchecked, asked=asked, result_extra=extra
    )


def record(entry: CommandLog, reply: dict | None) -> None:
    if reply is None:
        entry.outcome = CommandLog.Outcome.TIMEOUT
        entry.error = f"No reply within {settings.COMMAND_TIMEOUT_S:g} s."
    else:
        entry.outcome = CommandLog.Outcome.OK if reply.get("ok") else CommandLog.Outcome.FAILED
        entry.response = reply
        entry.error = reply.get("error") or ""
    entry.answered_at = timezone.now()
    if entry.pk is None:  # its first write failed: this one stores it whole
        entry.save()
    else:
        entry.save(update_fields=["outcome", "response", "error", "answered_at"])


async def execute(
    prepared: Prepared,
    *,
    timeout: float | None = None,
    after_answer: list[Callable[[], None]] | None = None,
) -> Outcome:
    """Publish to `<id>/control/in` (workers.direct: this process's own broker connection,
    else a gateway through the outbox) and wait for the drone's own reply.

    The drone's new target is stored before this returns: the envelope check of the next
    command starts from it. The log entry is written with its answer, unless the caller
    passes `after_answer`, a list it runs (synchronously) once it has answered its own
    caller, so that writing it is not on the way back to the operator.
    """
    entry = prepared.entry
    entry.sent_at = timezone.now()
    request = protocol.ControlRequest(entry.request_id, prepared.command, prepared.params)
    reply = await _answer_logging_pending(
        direct.arequest(prepared.drone.drone_id, "control", request.to_dict(), timeout=timeout),
        entry,
    )
    if envelopes.moves_target(prepared.command, reply):
        await sync_to_async(envelopes.remember_target)(prepared.drone, prepared.command, reply)
    if prepared.asked in HOME_COMMANDS:
        answered_hook = import_string(settings.AIRSPACE_RETURN_ANSWERED)
        await sync_to_async(answered_hook)(prepared.drone, prepared.asked, reply)
    if reply is not None and reply.get("ok") and prepared.result_extra:
        reply = {**reply, "result": {**(reply.get("result") or {}), **prepared.result_extra}}
    # Later, it still knows the request it answers (the audit trail names its address).
    answered = partial(contextvars.copy_context().run, record, entry, reply)
    if after_answer is None:
        await sync_to_async(answered)()
    else:
        after_answer.append(answered)
    return Outcome(request.request_id, prepared.command, reply)


async def _answer_logging_pending(
    answer: Coroutine[Any, Any, dict | None], entry: CommandLog
) -> dict | None:
    """The drone's answer. One that takes longer than COMMAND_LOG_PENDING_AFTER_S has its
    entry written as pending meanwhile, so a command still on its way is in the log; a
    quick one is written once, with its outcome (`record`): a write less per command, and
    no database work beside the command while it travels."""
    waiting = asyncio.ensure_future(answer)
    try:
        done, _ = await asyncio.wait({waiting}, timeout=settings.COMMAND_LOG_PENDING_AFTER_S)
        if done:
            return waiting.result()
        await _save_pending(entry)
        return await waiting
    except asyncio.CancelledError:
        # The caller went away (a closed connection): the command may be on its way.
        waiting.cancel()
        if entry.pk is None:
            await asyncio.shield(_save_pending(entry))
        raise


async def _save_pending(entry: CommandLog) -> None:
    try:
        await sync_to_async(entry.save)()
    except DatabaseError:
        log.warning("command %s not logged yet; retried with its answer", entry.request_id)


async def send(
    user: Any, drone_id: str, command: str, params: dict | None, confirmed: bool = False
) -> Outcome:
    """prepare + execute, for async callers (views, tests, other apps)."""
    prepared = await sync_to_async(prepare)(user, drone_id, command, params, confirmed)
    return await execute(prepared)


# -- Drone Identifier queries ------------------------------------------------------------


def discover(user: Any) -> dict:
    """`discover`: the user's drones with their state, specs and sensors."""
    drones = Drone.objects.for_user(user).order_by("drone_id")
    return {"drones": [drone_summary(d) for d in drones]}


def drone_summary(drone: Drone) -> dict:
    return {
        "drone_id": drone.drone_id,
        "online": drone.online,
        "last_seen": drone.last_seen.isoformat() if drone.last_seen else None,
        "position": drone.position,
        "battery": drone.battery,
        "armed": drone.armed,
        "airborne": drone.airborne,
        "specs": drone.specs,
        "sensors": drone.sensors,
        "mission": drone.mission,
    }


def gear(drone: Drone) -> dict:
    return {"drone_id": drone.drone_id, "specs": drone.specs, "sensors": drone.sensors}


# -- Mission Planner hooks ---------------------------------------------------------------


def mission_start_stop_handler(command: str):  # type: ignore[no-untyped-def]
    """The function settings.MISSION_START_STOP_HANDLERS names for startchain / stopchain."""
    return import_string(settings.MISSION_START_STOP_HANDLERS[command])


def check_mission_start_stop(user: Any, drone_id: str) -> Drone:
    """The checks startchain and stopchain share: drone (404), role (403), online (409)."""
    drone = find_drone(user, drone_id)
    if not _may_operate(drone):
        raise CommandRefused(403, "Only operators and admins may command drones.")
    if not drone.online:
        raise CommandRefused(409, f"Drone {drone.drone_id} is offline.")
    return drone


def run_mission_start_stop(
    user: Any, drone_id: str, command: str, mission: object = None, confirmed: bool = False
) -> dict:
    """startchain / stopchain through the configured hook, after the shared checks;
    `confirmed` lets a startchain go beyond the envelope's defaults."""
    drone = check_mission_start_stop(user, drone_id)
    hook = mission_start_stop_handler(command)
    if command == "startchain":
        if not isinstance(mission, str) or not mission:
            raise CommandRefused(400, "mission: is required", "mission")
        return hook(drone=drone, user=user, mission=mission, confirmed=confirmed)
    return hook(drone=drone, user=user)
