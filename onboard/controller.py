"""Command executor: control commands (docs/protocol.md) → flight-controller calls, typed errors.

Control requests from the ground and mission steps both go through `Controller.execute`,
so a step behaves exactly like the same command sent by hand.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any

from . import protocol
from .envelope import FROM_HERE_NOTE, command_starts
from .fc.base import FlightController, FlightControllerError
from .navigation import NavigationError, NavigationProcessor, current_ned

log = logging.getLogger(__name__)

# Called with (kind, details) for the logger: "command", "response", "arming".
EventSink = Callable[[str, dict], None]
# Called with (command, target kind, target NED, vehicle state, is a mission step, where
# the leg starts: the last target, else the position): a refusal sentence or None.
Guard = Callable[[str, str, tuple, Any, bool, tuple | None], str | None]


class CommandError(Exception):
    """A command that could not be carried out; str() is a sentence for the reply."""


class Controller:
    def __init__(
        self,
        fc: FlightController,
        navigation: NavigationProcessor,
        *,
        gear: Any = None,
        arm_timeout: float = 15.0,
        events: EventSink | None = None,
        guard: Guard | None = None,
        on_arm: Callable[[], None] | None = None,
    ) -> None:
        self.fc = fc
        self.guard = guard
        # Told of every arm asked for, before it is sent (the fail-safe's landed state).
        self.on_arm = on_arm or (lambda: None)
        self.navigation = navigation
        self.gear = gear
        self.arm_timeout = arm_timeout
        self.events = events or (lambda kind, details: None)
        # Commands the agent carries out itself (operator hold and return), by name.
        self.actions: dict[str, Callable[[dict, dict], dict]] = {}

    def handle(self, request: protocol.ControlRequest) -> protocol.ControlResponse:
        """Run a parsed control request and build its response (never raises)."""
        self.events(
            "command",
            {
                "request_id": request.request_id,
                "command": request.command,
                "params": request.params,
            },
        )
        try:
            result = self.execute(request.command, request.params)
            response = protocol.ControlResponse(request.request_id, request.command, True, result)
        except CommandError as exc:
            response = protocol.ControlResponse(
                request.request_id, request.command, False, None, str(exc)
            )
        self.events(
            "response",
            {
                "request_id": request.request_id,
                "command": request.command,
                "ok": response.ok,
                "error": response.error,
            },
        )
        return response

    def execute(self, command: str, params: dict, *, context: dict | None = None) -> dict:
        """Carry out one validated command; return its result or raise CommandError."""
        handler = self.actions.get(command) or getattr(self, f"_do_{command}", None)
        if handler is None:
            raise CommandError(f"The command {command!r} is not supported by this drone.")
        try:
            return handler(params, context or {})
        except CommandError:
            raise
        except NavigationError as exc:
            raise CommandError(str(exc)) from exc
        except FlightControllerError as exc:
            raise CommandError(_sentence(exc, f"The flight controller refused {command}")) from exc
        except Exception as exc:  # a driver bug must become a reply, not a dead agent
            log.exception("command %s failed", command)
            raise CommandError(f"{command} failed unexpectedly: {exc}.") from exc

    # -- arming ---------------------------------------------------------------------------

    def _do_arm(self, params: dict, context: dict) -> dict:
        self.on_arm()
        if self.fc.state.armed:
            return {"armed": True}
        self.events("arming", {"action": "arm", "phase": "requested"})
        try:
            self.fc.arm(timeout=self.arm_timeout)
        finally:
            self.events("arming", {"action": "arm", "phase": "done", "armed": self.fc.state.armed})
        return {"armed": self.fc.state.armed}

    def _do_disarm(self, params: dict, context: dict) -> dict:
        state = self.fc.state
        if state.airborne and not params.get("force"):
            raise CommandError(
                "The drone is airborne; land before disarming, or send force to disarm anyway."
            )
        if not state.armed and not state.arming:
            return {"armed": False}
        self.events("arming", {"action": "disarm", "phase": "requested"})
        try:
            self.fc.disarm(timeout=self.arm_timeout)
        finally:
            self.events(
                "arming", {"action": "disarm", "phase": "done", "armed": self.fc.state.armed}
            )
        return {"armed": self.fc.state.armed}

    # -- navigation -----------------------------------------------------------------------

    def _navigate(self, command: str, params: dict, context: dict) -> dict:
        if not self.fc.state.armed:
            raise CommandError(f"The drone is not armed; arm it before {command}.")
        if self.guard is not None:  # the flight envelope, checked before the target is sent
            state = self.fc.state
            planned = self.navigation.plan(command, params, state)
            last = self.navigation.last_target
            here = current_ned(state)
            in_mission = "mission_id" in context
            # The leg from the last target, and from where the drone is while it is still
            # on its way there (onboard/envelope.py command_starts).
            starts = command_starts(last.ned if last is not None else None, here)
            for start in starts:
                refusal = self.guard(command, planned.kind, planned.ned, state, in_mission, start)
                if refusal is None:
                    continue
                if len(starts) > 1 and start is starts[-1]:
                    refusal = refusal.rstrip(".") + FROM_HERE_NOTE + "."
                raise CommandError(refusal)
        target = self.navigation.execute(command, params)
        north, east, down = target.ned
        return {"target": {"north": north, "east": east, "down": down}}

    def _do_takeoff(self, params: dict, context: dict) -> dict:
        return self._navigate("takeoff", params, context)

    def _do_land(self, params: dict, context: dict) -> dict:
        return self._navigate("land", params, context)

    def _do_changeN(self, params: dict, context: dict) -> dict:  # noqa: N802 (command name)
        return self._navigate("changeN", params, context)

    def _do_changeE(self, params: dict, context: dict) -> dict:  # noqa: N802 (command name)
        return self._navigate("changeE", params, context)

    def _do_altitude(self, params: dict, context: dict) -> dict:
        return self._navigate("altitude", params, context)

    def _do_navigate(self, params: dict, context: dict) -> dict:
        return self._navigate("navigate", params, context)

    # -- gear and objects -----------------------------------------------------------------

    def _do_takepic(self, params: dict, context: dict) -> dict:
        if self.gear is None:
            raise CommandError("This drone has no gear manager, so no camera.")
        try:
            return self.gear.take_picture(self.fc.state, context)
        except Exception as exc:
            raise CommandError(_sentence(exc, "The picture could not be taken")) from exc

    def _do_objrequest(self, params: dict, context: dict) -> dict:
        # docs/protocol.md: the result is the object's latest fields, as the board names them.
        return dict(self.fc.request_object(params["value"]))

    # -- link and board -------------------------------------------------------------------

    def _do_resetfc(self, params: dict, context: dict) -> dict:
        if self.fc.state.airborne and not params.get("force"):
            raise CommandError(
                "The drone is airborne; rebooting the flight controller would drop it. "
                "Send force to reboot anyway."
            )
        self.fc.reset()
        self.navigation.reset()
        return {"reset": True}

    def _do_rebuildtelemetry(self, params: dict, context: dict) -> dict:
        self.fc.rebuild_link()
        return {"rebuilt": True}


def _sentence(exc: BaseException, fallback: str) -> str:
    text = str(exc).strip() or fallback
    return text if text.endswith((".", "!", "?")) else text + "."
