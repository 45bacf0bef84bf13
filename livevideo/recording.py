"""Recording each stream on the ground: WebM (VP8) files written off the event loop.

The relay hands every decoded frame to the stream's recorder, whose queue holds at most
``QUEUE_FRAMES``: when the disk or the encoder falls behind, frames are dropped (counted),
never held in memory and never waited for by the relay. A recording stops growing at
``max_bytes`` (it is kept, marked truncated). Frames keep their capture time drawn into
the picture (onboard/framecode.py), so a player can put each one on the flight's clock.
"""

from __future__ import annotations

import queue
import threading
import time
from dataclasses import dataclass
from datetime import UTC, datetime
from fractions import Fraction
from pathlib import Path
from typing import Any

import av

QUEUE_FRAMES = 30
BITRATE = 500_000
TIME_BASE = Fraction(1, 1000)
ENCODER_OPTIONS = {"deadline": "realtime", "cpu-used": "8", "lag-in-frames": "0"}


@dataclass
class Recorded:
    path: Path
    started_at: datetime
    ended_at: datetime
    frames: int
    dropped: int
    size: int
    width: int
    height: int
    truncated: bool


# A wall-clock reading is paired with a monotonic one only when the two were read within
# this long of each other: a thread preempted between the reads (tens of ms on a busy
# machine) would shift every frame's place on the wall clock by the pause.
PAIR_SPREAD_S = 0.001
PAIR_TRIES = 10


def clock_pair() -> tuple[datetime, float]:
    """The wall clock and the monotonic clock at one moment: the tightest of a few
    readings of the monotonic clock on either side of the wall clock's."""
    best: tuple[float, datetime, float] | None = None
    for _ in range(PAIR_TRIES):
        before = time.monotonic()
        wall = datetime.now(UTC)
        after = time.monotonic()
        if best is None or after - before < best[0]:
            best = (after - before, wall, (before + after) / 2)
        if after - before <= PAIR_SPREAD_S:
            break
    return best[1], best[2]


class Recorder:
    def __init__(self, path: Path, max_bytes: int) -> None:
        self.path = path
        self.max_bytes = max_bytes
        self._queue: queue.Queue = queue.Queue(maxsize=QUEUE_FRAMES)
        self.started_at, self._start = clock_pair()
        self.frames = self.dropped = self.width = self.height = 0
        self.truncated = False
        self._thread = threading.Thread(target=self._write, name=f"record {path.name}", daemon=True)
        self._thread.start()

    def offer(self, frame: Any) -> None:
        """Queue a decoded frame (its pixels are copied here); dropped when behind."""
        if self.truncated:
            return
        copy = av.VideoFrame.from_ndarray(frame.to_ndarray(format="yuv420p"), format="yuv420p")
        copy.pts = int((time.monotonic() - self._start) / TIME_BASE)
        copy.time_base = TIME_BASE
        try:
            self._queue.put_nowait(copy)
        except queue.Full:
            self.dropped += 1

    def close(self) -> Recorded | None:
        """Finish the file; None when no frame was written (the file is removed)."""
        self._queue.put(None)
        self._thread.join(30)
        ended = datetime.now(UTC)
        if self.frames == 0:
            self.path.unlink(missing_ok=True)
            return None
        return Recorded(self.path, self.started_at, ended, self.frames, self.dropped,
                        self.path.stat().st_size, self.width, self.height, self.truncated)  # fmt: skip

    def _write(self) -> None:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        container = av.open(str(self.path), "w", format="webm")
        stream = None
        written = 0
        last_pts = -1
        try:
            while (frame := self._queue.get()) is not None:
                if self.truncated:
                    continue
                if stream is None:
                    stream = container.add_stream("libvpx", rate=30)
                    stream.width, stream.height = self.width, self.height = (
                        frame.width,
                        frame.height,
                    )
                    stream.pix_fmt, stream.bit_rate = "yuv420p", BITRATE
                    # libvpx's real-time mode: its default ("good", 25 frames of
                    # look-ahead) costs several times the CPU of the live encoders.
                    stream.codec_context.options = ENCODER_OPTIONS
                    stream.codec_context.time_base = TIME_BASE
                if (frame.width, frame.height) != (self.width, self.height):
                    frame = frame.reformat(width=self.width, height=self.height)
                frame.pts = max(frame.pts, last_pts + 1)  # strictly increasing for the muxer
                last_pts = frame.pts
                for packet in stream.encode(frame):
                    written += packet.size
                    container.mux(packet)
                self.frames += 1
                if written >= self.max_bytes:
                    self.truncated = True
            if stream is not None:
                for packet in stream.encode(None):
                    container.mux(packet)
        finally:
            container.close()
