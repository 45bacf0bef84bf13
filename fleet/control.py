"""The `/control` endpoint, compatible with the REST command set of [Paula 2018], table 4.2
(docs/protocol.md).

Same parameter names and GET/POST split as that table, as query string or form fields.
It answers when the drone answers: `{"ok": true, "request_id", "result"}`; otherwise
`{"ok": false, "error"}` with 400, 401/403, 404, 405 (wrong method for the command),
409 (offline, unsafe, or refused by the drone; a refusal's `code` too, and for
`not_airworthy` each reason in `reasons`), 504 (no reply in time).
"""

from __future__ import annotations

from typing import Any

from asgiref.sync import sync_to_async
from django.conf import settings
from drf_spectacular.utils import OpenApiResponse, extend_schema, inline_serializer
from rest_framework import serializers
from rest_framework.request import Request
from rest_framework.response import Response

from config.throttling import COMMAND_THROTTLES, TogetherThrottles

from . import commands
from .async_views import AsyncAPIView
from .commands import CommandRefused

# `/control` parameter → command parameter (the names are the same; these are the ones passed on).
COMMAND_PARAMS = ("value", "lat", "lon", "altitude_delta", "altitude", "force")


class ControlParams(serializers.Serializer):
    command = serializers.ChoiceField(choices=commands.ALL_COMMANDS)
    droneID = serializers.CharField(required=False, help_text="identifier of the target drone")  # noqa: N815
    value = serializers.CharField(
        required=False, help_text="metres (changeN/changeE/altitude) or object name (objrequest)"
    )
    lat = serializers.FloatField(required=False, help_text="navigate: target latitude")
    lon = serializers.FloatField(required=False, help_text="navigate: target longitude")
    altitude_delta = serializers.FloatField(required=False, help_text="navigate: climb, m")
    altitude = serializers.FloatField(required=False, help_text="takeoff: height, m (default 10)")
    force = serializers.BooleanField(required=False, help_text="disarm/resetfc while airborne")
    mission = serializers.CharField(required=False, help_text="startchain: base64 mission steps")
    confirm_beyond_defaults = serializers.BooleanField(
        required=False, help_text="confirmed: a move beyond the envelope's defaults is sent"
    )


CONTROL_OK = inline_serializer(
    "ControlReply",
    {
        "ok": serializers.BooleanField(),
        "request_id": serializers.CharField(required=False),
        "result": serializers.DictField(),
    },
)
CONTROL_ERROR = inline_serializer(
    "ControlError",
    {
        "ok": serializers.BooleanField(),
        "error": serializers.CharField(),
        "code": serializers.CharField(required=False),
        "request_id": serializers.CharField(required=False),
        "reasons": serializers.ListField(
            child=serializers.CharField(),
            required=False,
            help_text="with `code: not_airworthy` only: every reason the drone may not fly",
        ),
    },
)
ERRORS = {
    status: OpenApiResponse(CONTROL_ERROR, description=text)
    for status, text in [
        (400, "bad or missing parameter"),
        (401, "not logged in"),
        (403, "not allowed"),
        (404, "unknown drone"),
        (405, "wrong method for this command"),
        (
            409,
            "drone offline, unsafe, or the drone refused; `code` outside_envelope or "
            "confirmation_required (resend with confirm_beyond_defaults=true), or "
            "not_airworthy (each reason in `reasons`)",
        ),
        (504, "no reply in time"),
    ]
}


def _error(
    status: int,
    message: str,
    request_id: str | None = None,
    code: str | None = None,
    reasons: list[str] | None = None,
) -> Response:
    body: dict[str, Any] = {"ok": False, "error": message}
    if code:
        body["code"] = code
    if reasons is not None:
        body["reasons"] = reasons
    if request_id:
        body["request_id"] = request_id
    return Response(body, status=status)


def _flag(value: Any) -> bool:
    """A form or query flag: true, 1, yes or on (any case) is set."""
    return value is True or str(value).strip().lower() in ("true", "1", "yes", "on")


def _cookie_command(request: Request) -> Response | None:
    """A GET that sends the drone a command answers only to an operate API token: a
    browser sends its cookie with any cross-site link or image, and a GET is not checked
    for CSRF, so a session (or a read-only token) may only read by GET."""
    if request.query_params.get("command") not in commands.DRONE_GET_COMMANDS:
        return None
    token = request.auth
    if token is None or getattr(token, "read_only", False):
        return _error(
            403,
            "command: objrequest by GET needs an operate API token (Authorization: Token); "
            "from a browser, POST /api/v1/drones/{id}/commands/ as the drone's page does",
        )
    return None


class ControlView(TogetherThrottles, AsyncAPIView):
    """The `/control` command set: every command, answered with the drone's own reply."""

    throttle_classes = COMMAND_THROTTLES

    @extend_schema(
        operation_id="control_get",
        parameters=[ControlParams],
        responses={200: CONTROL_OK, **ERRORS},
        description=(
            "GET commands: discover, getgear, objrequest. objrequest asks the drone, so it "
            "needs an operate API token (`Authorization: Token …`): a session cookie or a "
            "read-only token gets 403."
        ),
    )
    async def get(self, request: Request) -> Response:
        refusal = _cookie_command(request)
        if refusal is not None:
            return refusal
        return await self.control(request, request.query_params, commands.GET_COMMANDS)

    @extend_schema(
        operation_id="control_post",
        request={"application/x-www-form-urlencoded": ControlParams},
        responses={200: CONTROL_OK, **ERRORS},
        description="POST commands: every other command of the `/control` command set.",
    )
    async def post(self, request: Request) -> Response:
        data = {**request.query_params.dict()}
        if hasattr(request.data, "dict"):
            data.update(request.data.dict())
        elif isinstance(request.data, dict):
            data.update(request.data)
        return await self.control(request, data, commands.POST_COMMANDS)

    def handle_exception(self, exc: Exception) -> Response:
        """Authentication and permission errors in the `{ok, error}` shape, not the API's."""
        response = super().handle_exception(exc)
        if isinstance(response.data, dict) and "error" in response.data:
            response.data = {"ok": False, "error": response.data["error"]}
        return response

    async def control(self, request: Request, data: Any, allowed: tuple[str, ...]) -> Response:
        command = data.get("command")
        if not command:
            return _error(400, "command: is required")
        if command not in commands.ALL_COMMANDS:
            return _error(400, f"command: unknown command {command!r}")
        if command not in allowed:
            method = "GET" if command in commands.GET_COMMANDS else "POST"
            return _error(405, f"command: use {method} for {command}")
        user = request.user
        try:
            if command == "discover":
                return Response(
                    {"ok": True, "result": await sync_to_async(commands.discover)(user)}
                )
            drone_id = data.get("droneID")
            if not drone_id:
                return _error(400, "droneID: is required")
            if command == "getgear":
                drone = await sync_to_async(commands.find_drone)(user, drone_id)
                return Response({"ok": True, "result": commands.gear(drone)})
            if command in commands.CHAIN_COMMANDS:
                return await self.chain(user, drone_id, command, data)
            params = {name: data[name] for name in COMMAND_PARAMS if name in data}
            confirmed = _flag(data.get("confirm_beyond_defaults"))
            outcome = await commands.send(user, drone_id, command, params, confirmed)
        except CommandRefused as refusal:
            return _error(
                refusal.status, refusal.message, code=refusal.code, reasons=refusal.reasons
            )
        if outcome.timed_out:
            return _error(
                504,
                f"No reply from {drone_id} within {settings.COMMAND_TIMEOUT_S:g} s.",
                outcome.request_id,
            )
        if not outcome.ok:
            return _error(
                409, outcome.reply.get("error") or "The drone refused.", outcome.request_id
            )
        return Response(
            {
                "ok": True,
                "request_id": outcome.request_id,
                "result": outcome.reply.get("result") or {},
            }
        )

    async def chain(self, user: Any, drone_id: str, command: str, data: Any) -> Response:
        result = await sync_to_async(commands.run_mission_start_stop)(
            user, drone_id, command, data.get("mission"), _flag(data.get("confirm_beyond_defaults"))
        )
        return Response({"ok": True, "result": result})
