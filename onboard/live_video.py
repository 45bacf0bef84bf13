"""Live video to the ground's media server: VP8 over WebRTC, published WHIP-style.

Video never delays a command or a telemetry sample, by construction:

- The camera, the encoder and the WebRTC stack run in a child process of their own
  (``python -m onboard.live_video``) with its own interpreter, event loop and a lower
  CPU priority (``nice``), so neither the GIL nor the CPU it needs is taken from the
  agent's MQTT, control and telemetry threads.
- The agent feeds it one pose per frame through a pipe it writes without blocking: when
  the pipe is full (the child is behind) the pose is dropped and counted, never queued.
  The child keeps only the newest pose, and renders a frame only when the encoder asks
  for one (a pull, not a queue), so a slow encoder or link lowers the frame rate instead
  of building a backlog.
- Over the link, WebRTC's congestion control sets the bitrate: the media server's
  receiver estimates the bandwidth it sees ([REMB]) and the encoder here follows every
  estimate it sends, up to 1.5 Mbit/s and down to 250 kbit/s, or to 30 kbit/s once the
  round trips of the RTCP reports show packets queueing on the link; there the picture's
  size follows the estimate too (onboard/video_adaptation.py: 640 x 480 → 320 x 240 →
  160 x 120, back up with hysteresis). The estimate is delay-based: it falls as soon as
  the link's queue grows, so the video leaves the link's capacity to the agent's MQTT
  traffic (commands, telemetry) rather than queueing ahead of it.
- The agent's MQTT connection crosses the same uplink, and the kernel knows how long its
  oldest unacknowledged byte has waited: the feeder reads it every 50 ms (``UplinkProbe``,
  Linux only) and tells the child the uplink's queue on the same pipe, within a frame
  rather than the second a receiver report takes, so the video pauses before commands'
  answers and telemetry wait long behind it.

Each frame carries its capture time drawn into its top rows (onboard/framecode.py),
read by the media server and the browser to show the glass-to-glass delay.

The drone authenticates with its broker credentials (drone id and password, HTTP Basic)
and may publish its own stream only; the media server checks both.
"""

from __future__ import annotations

import argparse
import asyncio
import base64
import fcntl
import json
import logging
import os
import signal
import socket
import struct
import subprocess
import sys
import threading
import time
import urllib.error
import urllib.parse
import urllib.request
from collections import Counter, deque
from collections.abc import Awaitable, Callable, Mapping
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path

from . import video_adaptation

log = logging.getLogger(__name__)

PASSWORD_ENV = "SKYHIVE_MEDIA_PASSWORD"
CLOCK_RATE = 90_000  # RTP clock of video payloads (RFC 3551 section 5)
PUBLISH_TIMEOUT_S = 10.0
RETRY_S = 2.0
# The niceness the publisher adds to its own (0-19), so that the agent's threads come
# first on a busy companion computer. A machine whose busy processes are not the agent's
# may set 0 in the agent's environment: at 10 beside nice-0 processes that keep a core
# busy, the publisher gets about a tenth of their share (the kernel's CFS weights, 110
# against 1024), too little to encode a frame.
NICE_ENV = "SKYHIVE_LIVE_VIDEO_NICE"
NICE = 10
SENDER_REPORTS_KEPT = 64  # sender reports whose sending time is noted
RESENT_KEPT = 4096  # the re-sent packets remembered (a sequence number wraps at 65536)
# "off": the uplink's queue is not measured from the MQTT connection, for a drone whose
# MQTT crosses another link than its video (its queue would say nothing of the video's).
UPLINK_ENV = "SKYHIVE_LIVE_VIDEO_UPLINK_QUEUE"
UPLINK_PROBE_S = 0.05
# Write samples kept, 30 s of them: a byte unacknowledged for longer reads as 30 s old.
UPLINK_KEPT = 600
# struct tcp_info (linux/tcp.h), the fields read by their byte offsets (checked with
# offsetof against the headers of Linux 6.18; unchanged since they were added, the
# structure only grows at its end): tcpi_bytes_acked (__u64, since Linux 4.1) and
# tcpi_min_rtt (__u32 microseconds, the least round trip of the last 5 minutes, 4.6).
TCP_INFO_BYTES_ACKED = 120
TCP_INFO_MIN_RTT = 148
TCP_INFO_LEN = 152
SIOCOUTQ = 0x5411  # linux/sockios.h: the bytes written and not yet acknowledged

Pose = tuple[tuple[float, float, float], tuple[float, float, float, float]]


@dataclass(frozen=True)
class LiveVideoConfig:
    media_url: str  # http://host:port of the media server
    drone_id: str
    password: str
    width: int = 320
    height: int = 240
    fps: float = 15.0

    def __post_init__(self) -> None:
        if not 1.0 <= self.fps <= 30.0:
            raise ValueError(f"live video frame rate must be within 1..30, got {self.fps}")
        if self.width % 2 or self.height % 2 or self.width < 128 or self.height < 96:
            raise ValueError(f"live video size {self.width}x{self.height} is not usable")

    @property
    def publish_url(self) -> str:
        return f"{self.media_url.rstrip('/')}/whip/{self.drone_id}"

    def argv(self) -> list[str]:
        return [
            sys.executable,
            "-m",
            "onboard.live_video",
            "--media-url",
            self.media_url,
            "--drone-id",
            self.drone_id,
            "--size",
            f"{self.width}x{self.height}",
            "--fps",
            str(self.fps),
        ]


# -- the agent's side: a child process fed with poses ------------------------------------


class LiveVideo:
    """Runs the publisher process and feeds it the drone's pose, never blocking."""

    def __init__(
        self,
        config: LiveVideoConfig,
        pose: Callable[[], Pose | None],
        *,
        enabled: Callable[[], bool] = lambda: True,
        uplink: Callable[[], socket.socket | None] | None = None,
    ) -> None:
        self.config = config
        self.pose = pose
        self.enabled = enabled
        if os.environ.get(UPLINK_ENV, "on") == "off":
            uplink = None
        self.uplink = UplinkProbe(uplink) if uplink is not None else None
        self.counts: Counter[str] = Counter()
        self._process: subprocess.Popen | None = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        self._thread = threading.Thread(target=self._feed, name="live-video", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(2)
        self._end_process()

    def _spawn(self) -> subprocess.Popen:
        env = dict(os.environ, **{PASSWORD_ENV: self.config.password})
        process = subprocess.Popen(
            self.config.argv(),
            stdin=subprocess.PIPE,
            env=env,
            cwd=str(Path(__file__).resolve().parent.parent),
        )
        assert process.stdin is not None
        fd = process.stdin.fileno()
        fcntl.fcntl(fd, fcntl.F_SETFL, fcntl.fcntl(fd, fcntl.F_GETFL) | os.O_NONBLOCK)
        self.counts["starts"] += 1
        return process

    def _end_process(self) -> None:
        process, self._process = self._process, None
        if process is None:
            return
        process.terminate()
        try:
            process.wait(5)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait(5)

    def _feed(self) -> None:
        # A pose per step too: the child keeps the newest, so more poses than frames is
        # harmless, and the uplink's queue is read at least every UPLINK_PROBE_S.
        period = min(1.0 / self.config.fps, UPLINK_PROBE_S)
        restart_at = 0.0
        while not self._stop.wait(period):
            if not self.enabled():
                self._end_process()
                continue
            if self._process is not None and self._process.poll() is not None:
                log.warning("live video process ended (%s)", self._process.returncode)
                self._process = None
                restart_at = time.monotonic() + RETRY_S
            if self._process is None:
                if time.monotonic() < restart_at:
                    continue
                self._process = self._spawn()
            self._send_uplink_queue()
            self._send_pose()

    def _send_pose(self) -> None:
        pose = self.pose()
        if pose is None:
            return
        sent = self._send([*pose[0], *pose[1]])
        self.counts["poses" if sent else "poses_dropped"] += 1

    def _send_uplink_queue(self) -> None:
        # A line an older child skips: it reads a list of 7 numbers only.
        queue_s = self.uplink.queue_s(time.monotonic()) if self.uplink is not None else None
        if queue_s is not None and self._send({"queue_s": round(queue_s, 3)}):
            self.counts["uplink_queues"] += 1

    def _send(self, value: object) -> bool:
        """Write one line to the child without blocking; False when it could not."""
        if self._process is None or self._process.stdin is None:
            return False
        try:
            os.write(self._process.stdin.fileno(), (json.dumps(value) + "\n").encode())
            return True
        except OSError:  # full (the child is behind: never wait for it) or closed
            return False


class UplinkProbe:
    """The queue on the uplink the agent's MQTT connection crosses: how long its oldest
    unacknowledged byte has waited, less the least round trip the connection has seen,
    from the kernel's counts (TCP_INFO and SIOCOUTQ; Linux). None where they cannot be
    read (another system, no connection): the round trips of the RTCP reports remain.

    Two system calls a sample, a few microseconds; the MQTT client's thread is not
    involved (the kernel answers for its socket)."""

    def __init__(self, connection: Callable[[], socket.socket | None]) -> None:
        self.connection = connection
        self.written: deque[tuple[float, int]] = deque(maxlen=UPLINK_KEPT)
        self._socket: socket.socket | None = None

    def queue_s(self, now: float) -> float | None:
        sock = self.connection()
        counts = _tcp_counts(sock) if sock is not None else None
        if counts is None:
            return None
        acked, unacked, least_rtt_s = counts
        if sock is not self._socket:  # a new connection counts from 0
            self._socket = sock
            self.written.clear()
        self.written.append((now, acked + unacked))
        while self.written[0][1] <= acked and len(self.written) > 1:
            self.written.popleft()
        wait = video_adaptation.uplink_wait_s(self.written, acked, now)
        return max(0.0, wait - least_rtt_s)


def _tcp_counts(sock: socket.socket) -> tuple[int, int, float] | None:
    """A TCP socket's bytes acknowledged, bytes written and not yet acknowledged, and
    least round trip (s); None where the kernel does not tell.

    TCP_INFO before SIOCOUTQ: an acknowledgement between the two then makes the written
    total (their sum) smaller, and the oldest byte's wait shorter, never longer."""
    try:
        info = sock.getsockopt(socket.IPPROTO_TCP, socket.TCP_INFO, TCP_INFO_LEN)
        outq = fcntl.ioctl(sock.fileno(), SIOCOUTQ, b"\0" * 4)
    except (OSError, AttributeError, ValueError):  # not Linux, not TCP, closed
        return None
    if len(info) < TCP_INFO_LEN:
        return None
    (acked,) = struct.unpack_from("=Q", info, TCP_INFO_BYTES_ACKED)
    (least_us,) = struct.unpack_from("=I", info, TCP_INFO_MIN_RTT)
    return acked, struct.unpack("=i", outq)[0], least_us / 1e6


# -- the child: camera, encoder, WebRTC ---------------------------------------------------


class LatestPose:
    """The newest pose read from standard input; older ones are simply overwritten."""

    def __init__(self) -> None:
        self.value: Pose = ((0.0, 0.0, -1.0), (0.0, 0.0, 0.0, 1.0))
        # Told each uplink queue the agent measured ({"queue_s": x} lines), from this
        # reading thread.
        self.on_uplink_queue: Callable[[float], None] | None = None

    def read_forever(self, stream) -> None:  # type: ignore[no-untyped-def]
        for line in stream:
            try:
                value = json.loads(line)
                if isinstance(value, dict):
                    self._uplink_queue(float(value["queue_s"]))
                    continue
                n, e, d, qx, qy, qz, qw = (float(v) for v in value)
            except (ValueError, TypeError, KeyError, RuntimeError):  # RuntimeError: loop closed
                continue
            self.value = ((n, e, d), (qx, qy, qz, qw))
        # The agent is gone (its end of the pipe closed): so is the reason to stream.
        os.kill(os.getpid(), signal.SIGTERM)

    def _uplink_queue(self, queue_s: float) -> None:
        if self.on_uplink_queue is not None:
            self.on_uplink_queue(queue_s)


class LinkAdaptation:
    """The link's newest bitrate estimate ([REMB], from the media server's receiver), the
    round trips of its RTCP reports, and the picture size and encoder target chosen for
    them (onboard/video_adaptation.py)."""

    def __init__(
        self, config: LiveVideoConfig, counts: Counter[str], clock: Callable[[], float]
    ) -> None:
        self.sizes = video_adaptation.ladder(config.width, config.height)
        self.fps = config.fps
        self.state = video_adaptation.Adaptation()
        self.estimate_bps: float | None = None
        self.paused_until = 0.0  # no frame is sent before this time (self.clock)
        self.uplink_queue_s: float | None = None  # the newest the agent measured
        self.on_resume: Callable[[], Awaitable[None]] | None = None  # told when it ends
        self.counts = counts
        self.clock = clock

    @property
    def size(self) -> video_adaptation.Size:
        return self.sizes[self.state.rung]

    def target_bps(self, default_bps: int, max_bps: int) -> int:
        estimate = self.estimate_bps if self.estimate_bps is not None else default_bps
        return video_adaptation.encoder_target_bps(estimate, max_bps, narrow=self.state.narrow)

    def estimate(self, bps: float) -> None:
        self.estimate_bps = bps
        self._update(video_adaptation.decide(self.state, self.sizes, self.fps, bps, self.clock()))

    def round_trip(self, rtt_s: float) -> None:
        if self.estimate_bps is None:
            return  # the session is still starting (video_adaptation: narrow link)
        self._update(video_adaptation.observe_rtt(self.state, rtt_s))
        pause = video_adaptation.pause_s(self.state)
        if pause:
            self.paused_until = max(self.paused_until, self.clock() + pause)
            self.counts["pauses"] += 1

    def uplink_queue(self, queue_s: float) -> None:
        """The uplink's queue the agent measured on its MQTT connection (UplinkProbe)."""
        self.uplink_queue_s = queue_s
        self._update(video_adaptation.observe_uplink_queue(self.state, queue_s))
        pause = video_adaptation.uplink_pause_s(queue_s)
        if pause:
            now = self.clock()
            if self.paused_until <= now:
                self.counts["uplink_pauses"] += 1
            self.paused_until = max(self.paused_until, now + pause)

    def _update(self, state: video_adaptation.Adaptation) -> None:
        before, was_narrow = self.size, self.state.narrow
        self.state = state
        if state.narrow != was_narrow:
            self.counts["narrow" if state.narrow else "wide"] += 1
            log.info("live video link %s (round trip least %.3f s, queue %.3f s, uplink queue "
                     "%s s, estimate %s bit/s)", "narrow" if state.narrow else "wide again",
                     state.least_rtt_s or 0.0, state.queue_s, self.uplink_queue_s,
                     self.estimate_bps)  # fmt: skip
        if self.size != before:
            self.counts[f"size_{self.size}"] += 1
            log.info("live video %s -> %s (link estimate %.0f kbit/s)", before, self.size,
                     (self.estimate_bps or 0) / 1000)  # fmt: skip


def adapt_sender(sender, adaptation: LinkAdaptation) -> None:  # type: ignore[no-untyped-def]
    """Feed `adaptation` the round trip of every receiver report about `sender`'s stream,
    and re-send a lost packet (RTCP NACK) once at most.

    aiortc's sender measures a round trip only from a report on its newest sender report,
    which never comes while its packets queue on the link (a newer one has been sent by
    then): the round trip is computed here from every report, from when the sender
    report it answers was sent (noted as it goes out: the report's own NTP time is that
    of the newest video packet, up to a frame period earlier, or a pause's length).
    """
    _note_round_trips(sender, adaptation)
    _resend_once(sender, adaptation)


def _note_round_trips(sender, adaptation: LinkAdaptation) -> None:  # type: ignore[no-untyped-def]
    """Each receiver report on `sender`'s stream gives `adaptation` a round trip."""
    from aiortc.rtp import RtcpRrPacket, RtcpSrPacket

    send_rtcp, handle = sender._send_rtcp, sender._handle_rtcp_packet
    sent: dict[int, float] = {}  # a sender report's LSR (RFC 3550) -> when it was sent

    async def send_rtcp_noting(packets) -> None:  # type: ignore[no-untyped-def]
        for packet in packets:
            if isinstance(packet, RtcpSrPacket):
                lsr = (packet.sender_info.ntp_timestamp >> 16) & 0xFFFFFFFF
                sent.pop(lsr, None)
                sent[lsr] = adaptation.clock()
                while len(sent) > SENDER_REPORTS_KEPT:
                    del sent[next(iter(sent))]
        await send_rtcp(packets)

    async def observed(packet) -> None:  # type: ignore[no-untyped-def]
        if isinstance(packet, (RtcpRrPacket, RtcpSrPacket)):
            for report in packet.reports:
                if report.ssrc == sender._ssrc and report.lsr in sent:
                    adaptation.round_trip(
                        video_adaptation.report_round_trip_s(
                            sent[report.lsr], report.dlsr, adaptation.clock()
                        )
                    )
        await handle(packet)

    sender._send_rtcp = send_rtcp_noting
    sender._handle_rtcp_packet = observed


def _resend_once(sender, adaptation: LinkAdaptation) -> None:  # type: ignore[no-untyped-def]
    """A lost packet (RTCP NACK) is re-sent once at most, never into a pause."""
    retransmit = sender._retransmit
    resent: dict[int, None] = {}  # the packets re-sent, oldest first
    deferred: dict[int, None] = {}  # asked for during a pause: re-sent when it ends

    async def retransmit_once(sequence_number: int) -> None:
        # aiortc's receiver asks again for every packet still missing each time it misses
        # another: re-sent at every request (or even once per round trip), the packets
        # took a narrow link over. Once each, and not into a queue the video is pausing
        # for (it would be lost there again): aiortc's receiver waits for a missing
        # packet until 512 more have come, so a packet never re-sent stops the picture.
        if sequence_number in resent:
            adaptation.counts["retransmissions_skipped"] += 1
            return
        if adaptation.paused_until > adaptation.clock():
            deferred[sequence_number] = None
            return
        resent[sequence_number] = None
        while len(resent) > RESENT_KEPT:
            del resent[next(iter(resent))]
        await retransmit(sequence_number)

    async def resume() -> None:
        waiting = list(deferred)
        deferred.clear()
        for sequence_number in waiting:
            await retransmit_once(sequence_number)

    sender._retransmit = retransmit_once
    adaptation.on_resume = resume


def use_adaptive_encoder(adaptation: LinkAdaptation) -> None:
    """Make this process's WebRTC senders encode VP8 with an encoder that tells
    `adaptation` of every estimate and follows it below aiortc's own floor.

    aiortc's VP8 encoder takes each estimate as its target, but never under 250 kbit/s:
    more than a narrow link carries, and the picture size is chosen for the estimate. The
    publisher process has one sender, so the encoder factory aiortc's sender calls is
    replaced for the whole process.
    """
    from aiortc import rtcrtpsender
    from aiortc.codecs import get_encoder

    encoder_class = _adaptive_vp8_encoder(adaptation)

    def encoder_for(codec):  # type: ignore[no-untyped-def]
        if codec.mimeType.lower() == "video/vp8":
            return encoder_class()
        return get_encoder(codec)

    rtcrtpsender.get_encoder = encoder_for


def _adaptive_vp8_encoder(adaptation: LinkAdaptation) -> type:
    """aiortc's VP8 encoder class, made to follow `adaptation` (use_adaptive_encoder)."""
    from aiortc.codecs.vpx import DEFAULT_BITRATE, MAX_BITRATE, Vp8Encoder

    class AdaptiveVp8Encoder(Vp8Encoder):
        """aiortc's VP8 encoder, its target set by `adaptation` and its keyframes paced.

        aiortc opens a new libvpx encoder (whose first frame is a keyframe) for a new
        size or a target more than 10 % away from the current one, and libvpx takes no
        new target otherwise. So every keyframe — asked for by the receiver, or made by a
        new target — waits until one is due (video_adaptation.keyframe_due); a new size
        takes the newest target at once.
        """

        keyframe_at: float | None = None
        keyframe_bytes = 0
        keyframe_wanted = False  # asked for, not yet due: sent once it is

        def encode(self, frame, force_keyframe: bool = False):  # type: ignore[no-untyped-def]
            now = adaptation.clock()
            wanted = force_keyframe or self.keyframe_wanted
            estimate = adaptation.estimate_bps or self.target_bitrate
            due = video_adaptation.keyframe_due(
                self.keyframe_at, self.keyframe_bytes, estimate, now
            )
            self.keyframe_wanted = wanted and not due
            if force_keyframe and not due:
                adaptation.counts["keyframes_deferred"] += 1
            resized = self.codec is not None and (frame.width, frame.height) != (
                self.codec.width,
                self.codec.height,
            )
            if due or resized:
                # The attribute aiortc's encoder reads its target (and its rate-control
                # buffer's size) from.
                self._Vp8Encoder__target_bitrate = adaptation.target_bps(  # type: ignore[attr-defined]
                    DEFAULT_BITRATE, MAX_BITRATE
                )
            codec = self.codec
            payloads, timestamp = super().encode(frame, wanted and due)
            if (wanted and due) or self.codec is not codec:  # a keyframe
                self.keyframe_at, self.keyframe_bytes = now, sum(len(p) for p in payloads)
            return payloads, timestamp

        @property
        def target_bitrate(self) -> int:
            return self._Vp8Encoder__target_bitrate  # type: ignore[attr-defined]

        @target_bitrate.setter
        def target_bitrate(self, bitrate: int) -> None:
            # An estimate from the receiver ([REMB]): the next due frame takes it.
            adaptation.estimate(bitrate)

    return AdaptiveVp8Encoder


def camera_track(
    config: LiveVideoConfig,
    poses: LatestPose,
    counts: Counter[str],
    adaptation: LinkAdaptation | None = None,
):  # type: ignore[no-untyped-def]
    """A WebRTC video track of the synthetic camera, each frame stamped with its capture
    time, at the size `adaptation` chooses (else the configured one). Rendered on
    demand: the encoder pulls one frame per period."""
    import av
    from aiortc.mediastreams import VideoStreamTrack

    from . import framecode
    from .synthetic_camera import render_view_rgb

    period = 1.0 / config.fps
    time_base = Fraction(1, CLOCK_RATE)

    class CameraTrack(VideoStreamTrack):
        def __init__(self) -> None:
            super().__init__()
            self._start: float | None = None
            self._next = 0.0

        async def recv(self) -> av.VideoFrame:
            loop = asyncio.get_running_loop()
            now = time.monotonic()
            if self._start is None:
                self._start, self._next = now, now
            if self._next > now:
                await asyncio.sleep(self._next - now)
            else:
                counts["late_frames"] += int((now - self._next) / period)
            self._next = max(self._next + period, time.monotonic())
            if adaptation is not None and adaptation.paused_until > adaptation.clock():
                counts["paused"] += 1
                # The link's queue is draining (video_adaptation.pause_s): no frame now.
                while (wait := adaptation.paused_until - adaptation.clock()) > 0:
                    await asyncio.sleep(wait)
                if adaptation.on_resume is not None:
                    await adaptation.on_resume()
                self._next = time.monotonic() + period
            rgb = await loop.run_in_executor(None, self._capture)
            frame = av.VideoFrame.from_ndarray(rgb, format="rgb24")
            frame.pts = int((time.monotonic() - self._start) * CLOCK_RATE)
            frame.time_base = time_base
            counts["frames"] += 1
            return frame

        def _capture(self):  # type: ignore[no-untyped-def]
            position, orientation = poses.value
            size = adaptation.size if adaptation is not None else config
            rgb = render_view_rgb(
                position, orientation, width=size.width, height=size.height
            ).copy()
            framecode.stamp(rgb, int(time.time() * 1000))
            return rgb

    return CameraTrack()


def _request(
    url: str, method: str, body: bytes | None, headers: dict[str, str]
) -> tuple[int, bytes, str]:
    request = urllib.request.Request(url, data=body, method=method, headers=headers)
    try:
        with urllib.request.urlopen(request, timeout=PUBLISH_TIMEOUT_S) as response:
            return response.status, response.read(), response.headers.get("Location", "")
    except urllib.error.HTTPError as exc:
        return exc.code, exc.read(), ""


def basic_auth(drone_id: str, password: str) -> str:
    return "Basic " + base64.b64encode(f"{drone_id}:{password}".encode()).decode()


async def publish_once(
    config: LiveVideoConfig, poses: LatestPose, counts: Counter[str], stopping: asyncio.Event
) -> None:
    """One WHIP session: offer, answer, stream until the connection ends."""
    from aiortc import RTCPeerConnection, RTCSessionDescription
    from aiortc.rtcrtpsender import RTCRtpSender

    adaptation = LinkAdaptation(config, counts, time.monotonic)
    use_adaptive_encoder(adaptation)
    loop = asyncio.get_running_loop()

    def uplink_queue(queue_s: float) -> None:  # from the pose pipe's reading thread
        loop.call_soon_threadsafe(adaptation.uplink_queue, queue_s)

    poses.on_uplink_queue = uplink_queue
    pc = RTCPeerConnection()
    ended = asyncio.Event()

    @pc.on("connectionstatechange")
    async def _changed() -> None:
        if pc.connectionState in ("failed", "closed"):
            ended.set()

    track = camera_track(config, poses, counts, adaptation)
    transceiver = pc.addTransceiver(track, direction="sendonly")
    adapt_sender(transceiver.sender, adaptation)
    vp8 = [c for c in RTCRtpSender.getCapabilities("video").codecs if c.mimeType == "video/VP8"]
    transceiver.setCodecPreferences(vp8)
    await pc.setLocalDescription(await pc.createOffer())
    headers = {
        "Content-Type": "application/sdp",
        "Authorization": basic_auth(config.drone_id, config.password),
    }
    status, body, location = await loop.run_in_executor(
        None, _request, config.publish_url, "POST", pc.localDescription.sdp.encode(), headers
    )
    if status != 201:
        await pc.close()
        counts["refused"] += 1
        raise PermissionError(f"media server answered {status}: {body[:200]!r}")
    await pc.setRemoteDescription(RTCSessionDescription(sdp=body.decode(), type="answer"))
    counts["sessions"] += 1
    log.info("live video published to %s", config.publish_url)
    try:
        # Until the connection ends or the process is asked to stop (then the session is
        # ended with a DELETE, so the media server frees it at once).
        waits = [asyncio.ensure_future(ended.wait()), asyncio.ensure_future(stopping.wait())]
        _, pending = await asyncio.wait(waits, return_when=asyncio.FIRST_COMPLETED)
        for task in pending:
            task.cancel()
    finally:
        poses.on_uplink_queue = None
        await pc.close()
        if location:
            url = urllib.parse.urljoin(config.publish_url, location)
            await loop.run_in_executor(None, _request, url, "DELETE", None, headers)


async def publish_forever(config: LiveVideoConfig, poses: LatestPose) -> None:
    counts: Counter[str] = Counter()
    stopping = asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGTERM, signal.SIGINT):
        loop.add_signal_handler(sig, stopping.set)
    while not stopping.is_set():
        try:
            await publish_once(config, poses, counts, stopping)
        except (OSError, PermissionError, ValueError) as exc:
            log.warning("live video not published: %s", exc)
        try:
            await asyncio.wait_for(stopping.wait(), RETRY_S)
        except TimeoutError:
            pass


def niceness(environ: Mapping[str, str]) -> int:
    """The niceness to add, from the environment (NICE when unset); a clear error if bad."""
    raw = environ.get(NICE_ENV, "").strip()
    if not raw:
        return NICE
    if not raw.isdigit() or int(raw) > 19:
        raise SystemExit(f"{NICE_ENV}={raw!r}: a whole number from 0 to 19 expected")
    return int(raw)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="Publish the camera to the media server.")
    parser.add_argument("--media-url", required=True)
    parser.add_argument("--drone-id", required=True)
    parser.add_argument("--size", default="320x240")
    parser.add_argument("--fps", type=float, default=15.0)
    args = parser.parse_args(argv)
    logging.basicConfig(
        level=logging.INFO,
        stream=sys.stderr,
        format="%(asctime)s live-video %(levelname)s %(name)s: %(message)s",
    )
    logging.getLogger("aioice").setLevel(logging.WARNING)  # one line per ICE check
    width, height = (int(v) for v in args.size.split("x"))
    config = LiveVideoConfig(
        args.media_url, args.drone_id, os.environ.get(PASSWORD_ENV, ""), width, height, args.fps
    )
    os.nice(niceness(os.environ))
    poses = LatestPose()
    threading.Thread(target=poses.read_forever, args=(sys.stdin,), daemon=True).start()
    asyncio.run(publish_forever(config, poses))
    return 0


if __name__ == "__main__":
    sys.exit(main())
