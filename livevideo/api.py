"""Live video in the portal's API (docs/video.md).

- `GET /api/v1/drones/{id}/video/`: whether the drone's stream is live, its glass-to-
  ground delay (ms), resolution, bitrate and frame rate, as the media server measures
  them, whether the media server answers (`media_server`), why there is no stream
  (`not_live`: media_server_unavailable, drone_offline, not_publishing; else null) and
  the server's clock (ms) so a page can correct its own.
- `POST /api/v1/drones/{id}/video/whep/`: a WHEP offer (application/sdp); the portal
  signs a viewer ticket for the member's organisation and passes the offer to the media
  server, which checks the ticket itself; answers 201 with the SDP answer and a
  `Location` to DELETE when done.
- `GET/POST /api/v1/drones/{id}/video/stills/`: the drone's stills from the stream (the
  newest 50), or take one now (operators and admins; livevideo.stills), with
  `…/stills/{n}/image/` and `…/thumbnail/`.
- `GET /api/v1/flights/{pk}/video/`: the recordings made during a flight (its drone's,
  overlapping its time), each with its offset on the flight's clock and its WebM file at
  `/api/v1/drones/{id}/video/recordings/{n}/file/`.
- `GET /api/v1/logs/{id}/video/`: the recordings a flight log's viewer plays in step
  with its plots (livevideo.logs: the log's drone, a log on Unix time, overlapping it).
- `GET /api/v1/missions/{id}/video/`: the recordings the mission log viewer plays in
  step with its cursor (livevideo.missions: those of the mission's flights).
- `GET/PUT /api/v1/organisations/{slug}/video-retention/`: how long the organisation
  keeps its recorded video and how much in all (`keep_days`, `max_bytes`; null for the
  platform's setting); members read, admins write (livevideo.retention).

Every member of the drone's organisation (any role) may watch; another organisation's
drone answers 404 (fleet.tenancy through `Drone.objects.for_user`).
"""

from __future__ import annotations

import re
import time
from datetime import datetime

from django.conf import settings
from django.core.exceptions import ValidationError
from django.db.models import Model, QuerySet
from django.http import FileResponse, HttpResponse
from drf_spectacular.types import OpenApiTypes
from drf_spectacular.utils import extend_schema
from rest_framework import exceptions
from rest_framework.parsers import BaseParser
from rest_framework.request import Request
from rest_framework.response import Response
from rest_framework.views import APIView

from fleet.lookups import organisation_or_404
from fleet.models import Drone, Role
from fleet.permissions import require_role
from logs.models import FlightLog
from missions.models import Mission
from records.models import FlightRecord

from . import client, ranges, retention, stills
from .flights import file_url, recordings_of
from .logs import recordings_of_log
from .missions import recordings_of_mission
from .models import VideoRecording, VideoStill

STILLS_LISTED = 50
# A range answer is read into memory: at most this much at once (the player asks again
# for the rest, as it does for any server that answers part of a range).
RANGE_CHUNK_BYTES = 4 * 1024 * 1024
SESSION_RE = re.compile(r"/whep/[A-Za-z0-9_-]+/(?P<session>[A-Za-z0-9_-]{1,64})$")


class SdpParser(BaseParser):
    media_type = "application/sdp"

    def parse(self, stream, media_type=None, parser_context=None) -> bytes:  # type: ignore[no-untyped-def]
        return stream.read() if stream is not None else b""


def _drone(request: Request, drone_id: str) -> Drone:
    drone = Drone.objects.for_user(request.user).filter(drone_id=drone_id).first()
    if drone is None:
        raise exceptions.NotFound(f"Unknown drone {drone_id!r}.")
    return drone


def _unavailable(exc: Exception) -> Response:
    return Response({"code": "media_server_unavailable", "detail": str(exc)}, status=503)


def why_not_live(drone: Drone, live: bool, media_server_answers: bool) -> str | None:
    """Why there is no stream to watch, as far as the ground knows: the media server does
    not answer, the drone is offline, or it is online and does not publish."""
    if live:
        return None
    if not media_server_answers:
        return "media_server_unavailable"
    return "not_publishing" if drone.online else "drone_offline"


class VideoView(APIView):
    """The drone's live stream: live, delay_ms, width, height, bitrate_bps, fps, and
    `not_live` (why there is none, else null)."""

    @extend_schema(responses={200: OpenApiTypes.OBJECT})
    def get(self, request: Request, drone_id: str) -> Response:
        drone = _drone(request, drone_id)
        try:
            state, available = client.describe(drone.drone_id), True
        except client.MediaServerUnavailable:
            # A state, not an error: the page says so and asks again later.
            state, available = {}, False
        return Response(
            {
                "drone": drone.drone_id,
                "live": bool(state.get("live")),
                "not_live": why_not_live(drone, bool(state.get("live")), available),
                "media_server": "available" if available else "unavailable",
                "delay_ms": state.get("delay_ms"),
                "width": state.get("width"),
                "height": state.get("height"),
                "bitrate_bps": state.get("bitrate_bps"),
                "fps": state.get("fps"),
                "teleop_max_delay_ms": settings.LIVE_VIDEO_TELEOP_MAX_DELAY_MS,
                "server_time_ms": round(time.time() * 1000),
                "watch_url": f"/api/v1/drones/{drone.drone_id}/video/whep/",
            }
        )


def _proxied(reply: client.Reply, drone_id: str) -> HttpResponse:
    response = HttpResponse(reply.body, status=reply.status, content_type=reply.content_type)
    location = reply.headers.get("Location") or reply.headers.get("location")
    match = SESSION_RE.search(location or "")
    if match:
        response["Location"] = f"/api/v1/drones/{drone_id}/video/whep/{match['session']}/"
    return response


class WatchView(APIView):
    """WHEP through the portal: POST an SDP offer, get the SDP answer (201)."""

    parser_classes = [SdpParser]

    @extend_schema(request={"application/sdp": OpenApiTypes.STR}, responses={201: OpenApiTypes.STR})
    def post(self, request: Request, drone_id: str) -> HttpResponse:
        drone = _drone(request, drone_id)
        if request.content_type.split(";")[0].strip() != "application/sdp":
            raise exceptions.UnsupportedMediaType(request.content_type)
        try:
            reply = client.watch(drone.drone_id, drone.organisation_id, request.data)
        except client.MediaServerUnavailable as exc:
            return _unavailable(exc)
        return _proxied(reply, drone.drone_id)


class WatchSessionView(APIView):
    """Ends a viewer's session (WHEP DELETE), proxied to the media server."""

    @extend_schema(request=None, responses={200: None, 404: None})
    def delete(self, request: Request, drone_id: str, session: str) -> HttpResponse:
        drone = _drone(request, drone_id)
        try:
            reply = client.unwatch(drone.drone_id, drone.organisation_id, session)
        except client.MediaServerUnavailable as exc:
            return _unavailable(exc)
        return _proxied(reply, drone.drone_id)


class StillsView(APIView):
    """Stills from the live stream: GET lists the drone's newest (members), POST takes
    one now (operators and admins), answered 201 with the still, 409 `not_live` when
    the drone is not streaming."""

    @extend_schema(responses={200: OpenApiTypes.OBJECT})
    def get(self, request: Request, drone_id: str) -> Response:
        drone = _drone(request, drone_id)
        rows = VideoStill.objects.filter(drone=drone).select_related("drone")[:STILLS_LISTED]
        return Response({"stills": [stills.describe(row) for row in rows]})

    @extend_schema(request=None, responses={201: OpenApiTypes.OBJECT})
    def post(self, request: Request, drone_id: str) -> Response:
        drone = _drone(request, drone_id)
        if not require_role(request.user, drone.organisation, Role.OPERATOR):
            raise exceptions.PermissionDenied("Only operators and admins take stills.")
        try:
            still = stills.take(drone, request.user)
        except stills.NotLive:
            return _not_live(f"{drone.drone_id} is not streaming.")
        except client.MediaServerUnavailable as exc:
            # No stream reaches the ground without the media server: nothing to take a
            # still from, as when the drone does not stream (the state says "unavailable").
            return _not_live(f"{drone.drone_id}'s stream cannot be reached: {exc}")
        return Response(stills.describe(still), status=201)


def _not_live(detail: str) -> Response:
    return Response({"code": "not_live", "detail": detail}, status=409)


def _still_file(request: Request, drone_id: str, pk: int, field: str) -> FileResponse:
    drone = _drone(request, drone_id)
    still = VideoStill.objects.filter(drone=drone, pk=pk).first()
    if still is None:
        raise exceptions.NotFound("Unknown still.")
    return FileResponse(getattr(still, field).open("rb"), content_type="image/jpeg")


class StillImageView(APIView):
    """A still's JPEG (members of the drone's organisation)."""

    @extend_schema(responses={(200, "image/jpeg"): OpenApiTypes.BINARY})
    def get(self, request: Request, drone_id: str, pk: int) -> FileResponse:
        return _still_file(request, drone_id, pk, "image")


class StillThumbnailView(APIView):
    """A still's thumbnail JPEG (members of the drone's organisation)."""

    @extend_schema(responses={(200, "image/jpeg"): OpenApiTypes.BINARY})
    def get(self, request: Request, drone_id: str, pk: int) -> FileResponse:
        return _still_file(request, drone_id, pk, "thumbnail")


def describe_recording(row: VideoRecording, flight_start: datetime | None = None) -> dict:
    return {
        "id": row.pk,
        "drone": row.drone.drone_id,
        "started_at": row.started_at.isoformat(),
        "ended_at": row.ended_at.isoformat(),
        # Where the recording starts on the flight's clock (seconds after the flight began).
        "offset_s": None
        if flight_start is None
        else (row.started_at - flight_start).total_seconds(),
        "frames": row.frames,
        "width": row.width,
        "height": row.height,
        "size": row.size,
        "truncated": row.truncated,
        "file": file_url(row),
    }


class FlightVideoView(APIView):
    """The video recorded during a flight: its drone's recordings overlapping the
    flight's time, each with its offset on the flight's clock."""

    @extend_schema(responses={200: OpenApiTypes.OBJECT})
    def get(self, request: Request, pk: int) -> Response:
        flight = FlightRecord.objects.for_user(request.user).filter(pk=pk).first()
        if flight is None or flight.drone_id is None:
            raise exceptions.NotFound("Unknown flight.")
        rows = recordings_of(flight)
        return Response(
            {
                "flight": flight.pk,
                "recordings": [describe_recording(r, flight.started_at) for r in rows],
            }
        )


def _visible(model: type, request: Request, pk: str, what: str):  # type: ignore[no-untyped-def]
    """The row of `model` with this pk in the user's organisations, or 404 (also for a
    pk that is not one: the address admits some that are not UUIDs)."""
    try:
        pk = model._meta.pk.to_python(pk)
    except ValidationError:
        raise exceptions.NotFound(f"Unknown {what}.") from None
    row = model.objects.for_user(request.user).filter(pk=pk).first()
    if row is None:
        raise exceptions.NotFound(f"Unknown {what}.")
    return row


def _recordings_answer(key: str, owner: Model, rows: QuerySet[VideoRecording]) -> Response:
    return Response({key: str(owner.pk), "recordings": [describe_recording(r) for r in rows]})


class LogVideoView(APIView):
    """The video a flight log's viewer plays on its time axis: the recordings of the
    log's drone overlapping the log's span, for a log stamped with Unix time."""

    @extend_schema(responses={200: OpenApiTypes.OBJECT})
    def get(self, request: Request, pk: str) -> Response:
        log = _visible(FlightLog, request, pk, "log")
        return _recordings_answer("log", log, recordings_of_log(log))


class MissionVideoView(APIView):
    """The video the mission log viewer plays on the mission's time axis: the recordings
    of the mission's flights (members of the mission's organisation)."""

    @extend_schema(responses={200: OpenApiTypes.OBJECT})
    def get(self, request: Request, pk: str) -> Response:
        mission = _visible(Mission, request, pk, "mission")
        return _recordings_answer("mission", mission, recordings_of_mission(mission))


def _file_or_range(request: Request, row: VideoRecording) -> HttpResponse:
    """The file, or the one byte range asked for (livevideo.ranges) so a player can seek."""
    size = row.file.size
    try:
        wanted = ranges.parse(request.headers.get("Range"), size)
    except ranges.Unsatisfiable:
        response = HttpResponse(status=416)
        response["Content-Range"] = f"bytes */{size}"
        return response
    if wanted is None:
        response = FileResponse(row.file.open("rb"), content_type="video/webm")
    else:
        with row.file.open("rb") as f:
            f.seek(wanted.first)
            body = f.read(min(wanted.length, RANGE_CHUNK_BYTES))
        response = HttpResponse(body, status=206, content_type="video/webm")
        served = ranges.ByteRange(wanted.first, wanted.first + len(body) - 1)
        response["Content-Range"] = served.content_range(size)
    response["Accept-Ranges"] = "bytes"
    return response


class RecordingFileView(APIView):
    """A recording's WebM file, whole or by one byte range (members of the drone's
    organisation)."""

    @extend_schema(
        responses={
            (200, "video/webm"): OpenApiTypes.BINARY,
            (206, "video/webm"): OpenApiTypes.BINARY,
        }
    )
    def get(self, request: Request, drone_id: str, pk: int) -> HttpResponse:
        drone = _drone(request, drone_id)
        row = VideoRecording.objects.filter(drone=drone, pk=pk).first()
        if row is None:
            raise exceptions.NotFound("Unknown recording.")
        return _file_or_range(request, row)


class RetentionView(APIView):
    """The organisation's recorded-video period and size cap, and what it holds now."""

    @extend_schema(responses={200: OpenApiTypes.OBJECT})
    def get(self, request: Request, slug: str) -> Response:
        return Response(retention.describe(organisation_or_404(request.user, slug)))

    @extend_schema(request=OpenApiTypes.OBJECT, responses={200: OpenApiTypes.OBJECT})
    def put(self, request: Request, slug: str) -> Response:
        organisation = organisation_or_404(request.user, slug)
        if not require_role(request.user, organisation, Role.ADMIN):
            raise exceptions.PermissionDenied("Only admins set how long video is kept.")
        try:
            return Response(retention.set_rule(organisation, request.data))
        except retention.RetentionError as exc:
            raise exceptions.ValidationError({exc.field: [exc.message]}) from None
