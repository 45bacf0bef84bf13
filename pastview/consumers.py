"""`/ws/pastview/<drone_id>/`: the past view of one drone, and teleoperation from it.

Server → client: a ``hello`` (what the user may do, the settings), the last snapshot the
service stored (so the background shows at once), then whatever ``manage.py pastview``
pushes to the drone's group: ``update`` (relative pose; the frame's JPEG only when the
choice changes), ``live``, ``status``, ``settings``.

Client → server, operators only: ``{"type": "teleop", "forward", "right", "up"}`` and
``{"type": "stop"}``. Moves go through the Drone Manager (fleet.commands: role, online and
parameter checks, command log, the drone's own reply). One move at most every
1 / PASTVIEW_TELEOP_HZ seconds; input arriving meanwhile replaces the waiting move, and
``stop`` (or the socket closing) discards it.
"""

from __future__ import annotations

import asyncio
import logging
import time
from typing import Any

from asgiref.sync import sync_to_async
from channels.db import database_sync_to_async
from django.conf import settings
from django.utils.module_loading import import_string

from config.throttling import TeleopRate
from fleet import commands
from fleet.consumers import CLOSE_NOT_FOUND, GroupConsumer
from fleet.models import Drone, Role
from fleet.permissions import require_role
from workers import outbox

from .models import ViewSettings
from .runner import WATCH_TTL_S, amark_watched, load_snapshot
from .service import group_name
from .teleop import BadInput, Stick, commands_for, heading_of

log = logging.getLogger(__name__)

# A move waits this long for the drone's reply: a later move supersedes it anyway.
TELEOP_REPLY_TIMEOUT_S = 3.0


@database_sync_to_async
def _drone_and_role(user, drone_id: str) -> tuple[Drone | None, bool]:  # type: ignore[no-untyped-def]
    drone = Drone.objects.for_user(user).select_related("organisation").filter(drone_id=drone_id)
    found = drone.first()
    if found is None:
        return None, False
    return found, require_role(user, found.organisation, Role.OPERATOR)


@database_sync_to_async
def _settings(drone: Drone) -> dict[str, Any]:
    return settings_dict(drone)


def settings_dict(drone: Drone) -> dict[str, Any]:
    row = ViewSettings.objects.filter(drone=drone).first()
    return (row or ViewSettings(drone=drone)).to_dict()


class PastViewConsumer(GroupConsumer):
    drone: Drone | None = None
    # Another organisation's drone is as unknown as none.
    refused_code = CLOSE_NOT_FOUND

    async def authorise(self, user: Any) -> tuple[Drone, bool] | None:
        drone, can_operate = await _drone_and_role(
            user, self.scope["url_route"]["kwargs"]["drone_id"]
        )
        if drone is None:
            return None
        # A session owing its organisation's second factor watches but does not steer.
        owes = database_sync_to_async(import_string(settings.SECOND_FACTOR_CHECK))
        return drone, can_operate and not await owes(
            user, drone.organisation, self.scope.get("session")
        )

    def group_for(self, target: tuple[Drone, bool]) -> str:
        return group_name(target[0].drone_id)

    async def joined(self, target: tuple[Drone, bool]) -> None:
        self.drone, self.can_operate = target
        self.heading: float | None = None
        # When (monotonic) this page last got a camera frame and a tracked pose of the drone.
        self.live_at: float | None = None
        self.tracked_at: float | None = None
        self.pending: Stick | None = None
        self.wakeup = asyncio.Event()
        self.worker: asyncio.Task | None = None
        # TELEOP_RATE per user (config/throttling.py), across their sockets.
        self.rate = TeleopRate(self.scope["user"])
        self.watch = asyncio.ensure_future(self._keep_watching(self.drone.drone_id))

    async def welcome(self, target: tuple[Drone, bool]) -> None:
        """Who may do what and the settings, then the last stored snapshot, if any."""
        drone, can_operate = target
        await self.send_json(
            {
                "type": "hello",
                "drone_id": drone.drone_id,
                "can_operate": can_operate,
                "settings": await _settings(drone),
            }
        )
        try:
            snapshot = await sync_to_async(load_snapshot)(drone.drone_id)
        except Exception:  # noqa: BLE001 - the page still works, it waits for the next frame
            log.exception("snapshot of %s unavailable", drone.drone_id)
            snapshot = None
        if snapshot is not None:
            self._note_heading(snapshot.get("update"))
            await self.send_json({"type": "snapshot", **snapshot})

    async def disconnect(self, code: int) -> None:
        await super().disconnect(code)
        for task in (getattr(self, "worker", None), getattr(self, "watch", None)):
            if task is not None:
                task.cancel()

    async def _keep_watching(self, drone_id: str) -> None:
        """Renew the drone's watch mark while the page is open, so the service pushes."""
        client = outbox.async_redis()
        while True:
            try:
                await amark_watched(client, drone_id)
            except Exception:  # noqa: BLE001 - without the mark the page only misses pushes
                log.warning("watch mark of %s not renewed", drone_id, exc_info=True)
            await asyncio.sleep(WATCH_TTL_S / 3)

    async def pastview_message(self, event: dict) -> None:
        """What the service pushed to the drone's group, passed on as it is."""
        message = event["message"]
        if message.get("type") == "update":
            self._note_heading(message)
            if message.get("tracking") == "tracked" and message.get("frame"):
                self.tracked_at = time.monotonic()
        elif message.get("type") == "live":
            self.live_at = time.monotonic()
        await self.send_json(message)

    def _note_heading(self, update: dict | None) -> None:
        try:
            self.heading = heading_of(update["pose"]["orientation"])  # type: ignore[index]
        except (KeyError, TypeError, ValueError):
            pass

    # -- teleoperation ------------------------------------------------------------------------

    async def receive_json(self, content: Any, **kwargs: object) -> None:
        kind = content.get("type") if isinstance(content, dict) else None
        if kind not in ("teleop", "stop"):
            await self._teleop_reply(False, "Unknown message type.")
            return
        if not self.can_operate:
            await self._teleop_reply(False, "Only operators and admins may command drones.")
            return
        if kind == "stop":  # never limited: stopping a drone must always get through
            self.pending = None
            return
        wait_s = await sync_to_async(self.rate.wait_s)()
        if wait_s is not None:
            await self._teleop_reply(False, f"Too many moves; try again in {wait_s:.1f} s.")
            return
        try:
            stick = Stick.parse(content)
        except BadInput as exc:
            await self._teleop_reply(False, f"Bad input: {exc}.")
            return
        if stick.idle:
            self.pending = None
            return
        self.pending = stick
        self.wakeup.set()
        if self.worker is None:
            self.worker = asyncio.ensure_future(self._move_loop())

    async def _move_loop(self) -> None:
        interval = 1.0 / settings.PASTVIEW_TELEOP_HZ
        last = -interval
        while True:
            await self.wakeup.wait()
            self.wakeup.clear()
            wait = last + interval - time.monotonic()
            if wait > 0:
                await asyncio.sleep(wait)
            stick, self.pending = self.pending, None
            if stick is None:  # stopped while waiting for the slot
                continue
            last = time.monotonic()
            try:
                await self._move(stick)
            except Exception:  # noqa: BLE001 - one failed move must not end teleoperation
                log.exception("teleoperation move for %s failed", self.drone)
                await self._teleop_reply(False, "The move failed on the ground; try again.")

    def stale_view(self) -> str | None:
        """Why the operator's view is too old to steer from, or None: moves are sent only
        while camera frames and tracked poses keep arriving (PASTVIEW_TELEOP_FRESH_S)."""
        limit = settings.PASTVIEW_TELEOP_FRESH_S
        now = time.monotonic()
        if self.live_at is None or now - self.live_at > limit:
            return f"No camera frame from the drone in the last {limit:g} s."
        if self.tracked_at is None or now - self.tracked_at > limit:
            return f"No tracked pose of the drone in the last {limit:g} s."
        return None

    async def _move(self, stick: Stick) -> None:
        if self.heading is None:
            await self._teleop_reply(False, "The drone's heading is not known yet (no pose).")
            return
        if stale := self.stale_view():
            await self._teleop_reply(False, f"{stale} Teleoperation needs a current view.")
            return
        assert self.drone is not None
        # The commands' log entries are written once the page has its answer.
        answered: list = []
        try:
            ok, error, sent = await self._send_moves(stick, answered)
            await self._teleop_reply(ok, error, sent)
        finally:
            for job in answered:
                await sync_to_async(job)()

    async def _send_moves(self, stick: Stick, answered: list) -> tuple[bool, str | None, list]:
        """The stick's commands in order, each after the previous one's reply (its envelope
        check starts from the target that reply set); stops at the first refusal."""
        assert self.drone is not None and self.heading is not None
        user = self.scope["user"]
        sent: list = []
        for command, value in commands_for(stick, self.heading, settings.PASTVIEW_TELEOP_STEP_M):
            try:
                prepared = await sync_to_async(commands.prepare)(
                    user, self.drone.drone_id, command, {"value": value}
                )
                outcome = await commands.execute(
                    prepared, timeout=TELEOP_REPLY_TIMEOUT_S, after_answer=answered
                )
            except commands.CommandRefused as exc:
                return False, exc.message, sent
            if not outcome.ok:
                error = "No reply from the drone." if outcome.timed_out else outcome.reply["error"]  # type: ignore[index]
                return False, error, sent
            sent.append({"command": command, "value": value})
        return True, None, sent

    async def _teleop_reply(self, ok: bool, error: str | None, sent: list | None = None) -> None:
        await self.send_json({"type": "teleop", "ok": ok, "error": error, "sent": sent or []})
