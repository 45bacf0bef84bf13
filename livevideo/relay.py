"""The media server's relay: one incoming stream per drone, fanned out to its viewers.

A drone publishes one VP8 video track (WHIP-style, [RFC 9725]); the relay decodes it,
reads each frame's capture time (onboard/framecode.py), keeps the newest frame for
stills, and hands every frame to each viewer's track, whose WebRTC sender encodes it for
that viewer's own link (the sender follows the viewer's REMB estimates, so a slow
viewer gets a lower bitrate without slowing the others or the drone).

Each viewer's track holds at most one frame: a viewer whose encoder or link falls behind
skips frames (counted) and never holds the drone's stream or other viewers back.

What bounds the cost (docs/security.md, "Live video"): at most ``max_streams`` streams
and ``max_viewers`` viewers (``max_viewers_per_stream`` each); an offer larger than
``max_offer_bytes`` is refused unread; a stream whose frames exceed ``max_width`` x
``max_height`` (as a keyframe declares, before it is decoded, or as decoded), whose
bitrate exceeds ``max_bitrate_bps`` over ``window_s``, whose packets do not decode, or
whose media never arrives is cut off; every refusal and cut is counted by reason.

Each stream is recorded on the ground when a recorder is given (livevideo/recording.py).
"""

from __future__ import annotations

import asyncio
import io
import logging
import secrets
import time
from collections import Counter
from collections.abc import Awaitable, Callable
from dataclasses import dataclass, field
from typing import Any

from aiortc import RTCPeerConnection, RTCSessionDescription
from aiortc.mediastreams import MediaStreamError, MediaStreamTrack
from aiortc.rtcrtpsender import RTCRtpSender

from onboard import framecode

from .jitter import skip_gap_before_keyframe, vp8_keyframe_size

log = logging.getLogger(__name__)

STALLED_S = 1.0  # packets without a frame this long: ask the drone for a keyframe


@dataclass(frozen=True)
class Limits:
    max_streams: int = 32
    max_viewers: int = 64
    max_viewers_per_stream: int = 8
    max_bitrate_bps: int = 4_000_000
    max_width: int = 1280
    max_height: int = 720
    max_offer_bytes: int = 64 * 1024
    window_s: float = 2.0
    # A stream with no decoded frame this long after it connected (or since the last
    # frame while packets keep coming) is cut off: it is not video this relay can show.
    no_frame_s: float = 10.0


class Refused(Exception):
    def __init__(self, status: int, code: str, detail: str = "") -> None:
        super().__init__(detail or code)
        self.status = status
        self.code = code


@dataclass
class StreamStats:
    started: float = field(default_factory=time.monotonic)
    frames: int = 0
    width: int = 0
    height: int = 0
    bytes_total: int = 0
    bitrate_bps: float = 0.0
    fps: float = 0.0
    delay_ms: float | None = None
    last_frame_at: float | None = None
    _window_start: float = field(default_factory=time.monotonic)
    _window_bytes: int = 0
    _window_frames: int = 0

    def roll(self, now: float, window_s: float) -> bool:
        """Close the measuring window when it is `window_s` old; True when it closed."""
        elapsed = now - self._window_start
        if elapsed < window_s:
            return False
        self.bitrate_bps = self._window_bytes * 8 / elapsed
        self.fps = self._window_frames / elapsed
        self._window_start, self._window_bytes, self._window_frames = now, 0, 0
        return True

    def as_dict(self) -> dict[str, Any]:
        return {
            "width": self.width,
            "height": self.height,
            "frames": self.frames,
            "fps": round(self.fps, 1),
            "bitrate_bps": round(self.bitrate_bps),
            "delay_ms": None if self.delay_ms is None else round(self.delay_ms, 1),
            "age_s": round(time.monotonic() - self.started, 1),
        }


def _new_peer() -> RTCPeerConnection:
    return RTCPeerConnection()


def _vp8_only(pc: RTCPeerConnection) -> None:
    vp8 = [c for c in RTCRtpSender.getCapabilities("video").codecs if c.mimeType == "video/VP8"]
    for transceiver in pc.getTransceivers():
        if transceiver.kind == "video":
            transceiver.setCodecPreferences(vp8)


async def _accept_offer(pc: RTCPeerConnection, sdp: str) -> None:
    try:
        await pc.setRemoteDescription(RTCSessionDescription(sdp=sdp, type="offer"))
    except Exception as exc:  # noqa: BLE001 - aiortc raises many kinds for a bad SDP
        raise Refused(400, "malformed_offer", f"the offer is not a usable SDP: {exc}") from exc
    videos = [t for t in pc.getTransceivers() if t.kind == "video"]
    if len(videos) != 1 or any(t.kind != "video" for t in pc.getTransceivers()):
        raise Refused(400, "malformed_offer", "the offer must hold exactly one video stream")
    _vp8_only(pc)


async def _answer(pc: RTCPeerConnection) -> str:
    try:
        await pc.setLocalDescription(await pc.createAnswer())
    except Exception as exc:  # noqa: BLE001 - no codec in common, bad directions
        raise Refused(400, "malformed_offer", f"no answer to this offer: {exc}") from exc
    sdp = pc.localDescription.sdp
    # Without a candidate the peer has nowhere to send: every media port is taken (a
    # full LIVE_VIDEO_UDP_PORTS range, livevideo/ports.py). Say so rather than answer.
    if "a=candidate:" not in sdp:
        raise Refused(503, "no_media_port", "every UDP port the media server may use is taken")
    return sdp


class ViewerTrack(MediaStreamTrack):
    """A viewer's video track: the newest frame only (a slow viewer skips frames)."""

    kind = "video"

    def __init__(self, counts: Counter[str]) -> None:
        super().__init__()
        self._queue: asyncio.Queue = asyncio.Queue(maxsize=1)
        self._counts = counts

    def offer(self, frame: Any) -> None:
        if self._queue.full():
            self._queue.get_nowait()
            self._counts["viewer_frames_skipped"] += 1
        self._queue.put_nowait(frame)

    async def recv(self) -> Any:
        if self.readyState != "live":
            raise MediaStreamError
        frame = await self._queue.get()
        if frame is None:
            raise MediaStreamError
        return frame

    def end(self) -> None:
        if self._queue.full():
            self._queue.get_nowait()
        self._queue.put_nowait(None)
        self.stop()


@dataclass
class Viewer:
    session: str
    pc: Any
    track: Any


@dataclass
class Stream:
    drone_id: str
    organisation_id: int
    session: str
    pc: Any
    stats: StreamStats = field(default_factory=StreamStats)
    viewers: dict[str, Viewer] = field(default_factory=dict)
    last_frame: Any = None
    recorder: Any = None
    ended: bool = False
    tasks: list[asyncio.Task] = field(default_factory=list)
    last_packet: tuple[float, Any, int] | None = None  # (when, receiver, ssrc)


class Relay:
    def __init__(
        self,
        limits: Limits | None = None,
        *,
        clock: Callable[[], float] = time.time,
        recorder: Callable[[str], Any] | None = None,
        on_recorded: Callable[[str, int, Any], Awaitable[bool]] | None = None,
    ) -> None:
        """`recorder(drone_id)` starts a recording of a new stream (livevideo.recording),
        `on_recorded(drone_id, organisation_id, recorded)` files each finished one (False:
        its drone is gone)."""
        self.limits = limits or Limits()
        self.recorder = recorder
        self.on_recorded = on_recorded
        self.streams: dict[str, Stream] = {}
        # Streams ended and still closing: their peers, viewers and recordings.
        self.ending = 0
        self.counts: Counter[str] = Counter()
        self.clock = clock

    # -- publishing -------------------------------------------------------------------------

    def check_offer_size(self, size: int) -> None:
        if size > self.limits.max_offer_bytes:
            self.counts["refused_oversize_offer"] += 1
            raise Refused(
                413, "offer_too_large", f"offers are at most {self.limits.max_offer_bytes} bytes"
            )

    async def publish(self, drone_id: str, organisation_id: int, sdp: str) -> tuple[str, str]:
        """Accept a drone's offer; (session id, answer SDP). A drone publishing again
        replaces its previous stream (it reconnected)."""
        self.check_offer_size(len(sdp.encode()))
        if drone_id not in self.streams and len(self.streams) >= self.limits.max_streams:
            self.counts["refused_too_many_streams"] += 1
            raise Refused(503, "too_many_streams")
        pc = _new_peer()
        stream = Stream(drone_id, organisation_id, secrets.token_urlsafe(12), pc)

        @pc.on("track")
        def _on_track(track) -> None:  # type: ignore[no-untyped-def]
            if track.kind == "video":
                stream.tasks.append(asyncio.ensure_future(self._consume(stream, track)))

        @pc.on("connectionstatechange")
        async def _changed() -> None:
            if pc.connectionState in ("failed", "closed"):
                await self.end(stream, "disconnected")

        try:
            await _accept_offer(pc, sdp)
            answer = await _answer(pc)
        except Refused as refused:
            self.counts[f"refused_{refused.code}"] += 1
            await pc.close()
            raise
        self._count_bytes(stream)
        previous = self.streams.get(drone_id)
        self.streams[drone_id] = stream
        if previous is not None:
            await self.end(previous, "replaced")
        stream.tasks.append(asyncio.ensure_future(self._watchdog(stream)))
        if self.recorder is not None:
            stream.recorder = self.recorder(drone_id)
        self.counts["published"] += 1
        return stream.session, answer

    def _count_bytes(self, stream: Stream) -> None:
        """Count the stream's RTP payload bytes as they arrive (its bitrate), and cut it
        off at once when a window holds more than the limit allows; a keyframe after a
        lost packet restarts the picture (livevideo/jitter.py)."""
        for transceiver in stream.pc.getTransceivers():
            receiver = transceiver.receiver
            handle = receiver._handle_rtp_packet

            async def counted(
                packet, arrival_time_ms: int, handle=handle, receiver=receiver
            ) -> None:  # type: ignore[no-untyped-def]
                if stream.ended:
                    return
                size = len(packet.payload)
                stream.stats.bytes_total += size
                stream.stats._window_bytes += size
                window_bits = stream.stats._window_bytes * 8
                if window_bits > self.limits.max_bitrate_bps * self.limits.window_s:
                    asyncio.ensure_future(self.cut_off(stream, "over_bitrate"))
                    return
                if self._declares_oversize(packet.payload):
                    asyncio.ensure_future(self.cut_off(stream, "oversize_frame"))
                    return
                stream.last_packet = (time.monotonic(), receiver, packet.ssrc)
                buffer = getattr(receiver, "_RTCRtpReceiver__jitter_buffer", None)
                if buffer is not None and skip_gap_before_keyframe(
                    buffer, packet.sequence_number, packet.payload
                ):
                    self.counts["gaps_skipped_at_keyframe"] += 1
                await handle(packet, arrival_time_ms=arrival_time_ms)

            receiver._handle_rtp_packet = counted

    def _declares_oversize(self, payload: bytes) -> bool:
        size = vp8_keyframe_size(payload)
        limits = self.limits
        return size is not None and (size[0] > limits.max_width or size[1] > limits.max_height)

    async def _consume(self, stream: Stream, track: MediaStreamTrack) -> None:
        while not stream.ended:
            try:
                frame = await track.recv()
            except MediaStreamError:
                break
            if frame.width > self.limits.max_width or frame.height > self.limits.max_height:
                await self.cut_off(stream, "oversize_frame")
                break
            self._frame(stream, frame)
        await self.end(stream, "track ended")

    def _frame(self, stream: Stream, frame) -> None:  # type: ignore[no-untyped-def]
        stats = stream.stats
        now = time.monotonic()
        stats.frames += 1
        stats._window_frames += 1
        stats.width, stats.height = frame.width, frame.height
        stats.last_frame_at = now
        captured = framecode.read(frame.to_ndarray(format="gray"))
        if captured is not None:
            stats.delay_ms = self.clock() * 1000 - captured
        stats.roll(now, self.limits.window_s)
        stream.last_frame = frame
        if stream.recorder is not None:
            stream.recorder.offer(frame)
        for viewer in list(stream.viewers.values()):
            viewer.track.offer(frame)

    async def _watchdog(self, stream: Stream) -> None:
        while not stream.ended:
            await asyncio.sleep(min(1.0, self.limits.window_s / 2))
            now = time.monotonic()
            if stream.stats.roll(now, self.limits.window_s) and stream.stats.frames == 0:
                stream.stats.fps = 0.0
            since = stream.stats.last_frame_at or stream.stats.started
            await self._ask_keyframe_when_stalled(stream, now, since)
            if now - since > self.limits.no_frame_s:
                reason = "undecodable" if stream.stats.bytes_total else "no_media"
                await self.cut_off(stream, reason)

    async def _ask_keyframe_when_stalled(self, stream: Stream, now: float, since: float) -> None:
        """Packets come but no frame for STALLED_S: one is missing, and aiortc's receiver
        would ask for a keyframe only after 512 more packets. Ask now (RTCP PLI, [RFC
        4585] section 6.3.1); the picture resumes at the keyframe (livevideo/jitter.py)."""
        if stream.last_packet is None:
            return
        arrived, receiver, ssrc = stream.last_packet
        if now - arrived < STALLED_S and now - since >= STALLED_S:
            self.counts["keyframes_asked"] += 1
            await receiver._send_rtcp_pli(ssrc)

    async def cut_off(self, stream: Stream, reason: str) -> None:
        if stream.ended:
            return
        self.counts[f"cut_off_{reason}"] += 1
        log.warning("stream of %s cut off: %s", stream.drone_id, reason)
        await self.end(stream, reason)

    async def end(self, stream: Stream, reason: str) -> None:
        if stream.ended:
            return
        stream.ended = True
        self.ending += 1
        try:
            await self._close(stream, reason)
        finally:
            self.ending -= 1

    async def _close(self, stream: Stream, reason: str) -> None:
        if self.streams.get(stream.drone_id) is stream:
            del self.streams[stream.drone_id]
        for viewer in list(stream.viewers.values()):
            await self._end_viewer(stream, viewer)
        current = asyncio.current_task()
        for task in stream.tasks:
            if task is not current:
                task.cancel()
        await stream.pc.close()
        log.info("stream of %s ended: %s", stream.drone_id, reason)
        await self._finish_recording(stream)

    async def _finish_recording(self, stream: Stream) -> None:
        recorder, stream.recorder = stream.recorder, None
        if recorder is None:
            return
        recorded = await asyncio.to_thread(recorder.close)
        if recorded is not None:
            await self._file(stream, recorded)

    async def _file(self, stream: Stream, recorded: Any) -> None:
        self.counts["recordings"] += 1
        if recorded.dropped:
            self.counts["recording_frames_dropped"] += recorded.dropped
        if self.on_recorded is None:
            return
        try:
            filed = await self.on_recorded(stream.drone_id, stream.organisation_id, recorded)
        except Exception:  # noqa: BLE001 - the file stays; the stream is over anyway
            self.counts["recordings_not_filed"] += 1
            log.exception("recording of %s not filed", stream.drone_id)
            return
        if not filed:
            self.counts["recordings_drone_gone"] += 1
            log.warning("recording of %s deleted: its drone is gone", stream.drone_id)

    async def unpublish(self, drone_id: str, session: str) -> bool:
        stream = self.streams.get(drone_id)
        if stream is None or stream.session != session:
            return False
        await self.end(stream, "unpublished")
        return True

    # -- watching ---------------------------------------------------------------------------

    def viewer_count(self) -> int:
        return sum(len(s.viewers) for s in self.streams.values())

    async def watch(self, drone_id: str, organisation_id: int, sdp: str) -> tuple[str, str]:
        """Accept a viewer's offer for a drone of `organisation_id` (from a verified
        ticket); (session id, answer SDP)."""
        self.check_offer_size(len(sdp.encode()))
        stream = self.streams.get(drone_id)
        if stream is None:
            raise Refused(404, "not_live", f"{drone_id} is not streaming")
        if stream.organisation_id != organisation_id:
            self.counts["refused_other_organisation"] += 1
            raise Refused(403, "other_organisation", "this drone belongs to another organisation")
        if (
            len(stream.viewers) >= self.limits.max_viewers_per_stream
            or self.viewer_count() >= self.limits.max_viewers
        ):
            self.counts["refused_too_many_viewers"] += 1
            raise Refused(503, "too_many_viewers")
        pc = _new_peer()
        track = ViewerTrack(self.counts)
        viewer = Viewer(secrets.token_urlsafe(12), pc, track)
        try:
            await _accept_offer(pc, sdp)
            pc.addTrack(track)
            _vp8_only(pc)
            answer = await _answer(pc)
        except Refused as refused:
            self.counts[f"refused_{refused.code}"] += 1
            await pc.close()
            raise

        @pc.on("connectionstatechange")
        async def _changed() -> None:
            if pc.connectionState in ("failed", "closed"):
                await self._end_viewer(stream, viewer)

        stream.viewers[viewer.session] = viewer
        if stream.last_frame is not None:
            track.offer(stream.last_frame)
        self.counts["viewers"] += 1
        return viewer.session, answer

    async def _end_viewer(self, stream: Stream, viewer: Viewer) -> None:
        if stream.viewers.pop(viewer.session, None) is None:
            return
        viewer.track.end()
        await viewer.pc.close()

    async def unwatch(self, drone_id: str, session: str) -> bool:
        stream = self.streams.get(drone_id)
        viewer = stream.viewers.get(session) if stream else None
        if stream is None or viewer is None:
            return False
        await self._end_viewer(stream, viewer)
        return True

    # -- what the portal reads --------------------------------------------------------------

    def describe(self, drone_id: str) -> dict[str, Any]:
        stream = self.streams.get(drone_id)
        if stream is None:
            return {"live": False}
        return {"live": True, "viewers": len(stream.viewers), **stream.stats.as_dict()}

    def describe_all(self) -> dict[str, dict[str, Any]]:
        return {drone_id: self.describe(drone_id) for drone_id in sorted(self.streams)}

    def still(self, drone_id: str) -> tuple[bytes, int | None] | None:
        """The newest frame as JPEG and its capture time (ms), or None when not live."""
        stream = self.streams.get(drone_id)
        if stream is None or stream.last_frame is None:
            return None
        frame = stream.last_frame
        buffer = io.BytesIO()
        frame.to_image().save(buffer, format="JPEG", quality=90)
        return buffer.getvalue(), framecode.read(frame.to_ndarray(format="gray"))

    def health(self) -> dict[str, Any]:
        return {
            "ok": True,
            "streams": len(self.streams),
            "viewers": self.viewer_count(),
            "streams_ending": self.ending,
            "counts": dict(self.counts),
            "limits": self.limits.__dict__,
        }

    async def close(self) -> None:
        for stream in list(self.streams.values()):
            await self.end(stream, "server stopping")
