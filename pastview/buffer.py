"""Per-drone buffer of past camera frames.

A frame is stored only when it is at least 25 cm or 10 degrees of yaw from the last
stored one, at most ``capacity`` frames are kept (30 by default: 15 s at 2 Hz, the
thresholds and size of [Nassar 2017]) and the
oldest is dropped first. Bad frames (out of order, corrupt JPEG, NaN pose) are dropped
and counted; the buffer never raises on bad input.

Storage is a preallocated array of twice the capacity used as a sliding window: frames
are appended at the end and, when the end is reached, the live ones are copied back to
the start. So the live frames are always one contiguous, chronological slice (what the
vectorised evaluation and the time-delay binary search need), at an amortised cost of
one copy per frame.
"""

from __future__ import annotations

import enum
import logging
import math
from dataclasses import dataclass, field

import numpy as np

from pastview.evaluation import FrameSet
from pastview.geometry import InvalidPose, Pose, yaw
from workers.images import open_image

log = logging.getLogger(__name__)

JPEG_SOI = b"\xff\xd8\xff"
JPEG_EOI = b"\xff\xd9"


class Outcome(enum.Enum):
    STORED = "stored"
    TOO_CLOSE = "too_close"
    OUT_OF_ORDER = "out_of_order"
    CORRUPT_JPEG = "corrupt_jpeg"
    BAD_POSE = "bad_pose"


@dataclass
class BufferStats:
    """How many frames went which way; ``repaired_quaternions`` were renormalised."""

    stored: int = 0
    too_close: int = 0
    out_of_order: int = 0
    corrupt_jpeg: int = 0
    bad_pose: int = 0
    evicted: int = 0
    repaired_quaternions: int = 0

    def to_dict(self) -> dict[str, int]:
        return dict(self.__dict__)


@dataclass(frozen=True, slots=True)
class Frame:
    """One stored frame: its id (unique per buffer, increasing), pose and JPEG bytes."""

    id: int
    pose: Pose
    jpeg: bytes = field(repr=False)


def is_valid_jpeg(data: bytes, *, decode: bool = True) -> bool:
    """True when data looks like a whole JPEG (start and end markers) and, if asked, decodes."""
    if not isinstance(data, bytes | bytearray) or len(data) < 4:
        return False
    body = bytes(data).rstrip(b"\x00")  # some encoders pad after the end marker
    if not body.startswith(JPEG_SOI) or not body.endswith(JPEG_EOI):
        return False
    if not decode:
        return True
    try:
        # A frame declaring more pixels than any camera has is refused before decoding.
        with open_image(body) as image:
            image.load()
    except Exception:  # Pillow raises OSError, SyntaxError, ValueError... on bad data
        return False
    return True


@dataclass
class FrameBuffer:
    """Frames of one drone, newest last. Not thread-safe: one owner feeds it."""

    capacity: int = 30
    min_distance_m: float = 0.25
    min_yaw_deg: float = 10.0
    decode_jpeg: bool = True
    stats: BufferStats = field(default_factory=BufferStats)

    def __post_init__(self) -> None:
        if self.capacity < 1:
            raise ValueError(f"capacity must be at least 1, got {self.capacity}")
        if not (self.min_distance_m >= 0 and self.min_yaw_deg >= 0):
            raise ValueError("thresholds must be non-negative")
        size = 2 * self.capacity
        self._ids = np.zeros(size, dtype=np.int64)
        self._ts = np.zeros(size)
        self._positions = np.zeros((size, 3))
        self._orientations = np.zeros((size, 4))
        self._inverse_rotations = np.zeros((size, 3, 3))
        self._anchors = np.zeros((size, 3))
        self._inverse_left = np.zeros((size, 4, 4))
        self._jpegs: list[bytes | None] = [None] * size
        self._start = 0
        self._end = 0
        self._next_id = 0

    def __len__(self) -> int:
        return self._end - self._start

    def add(self, ts: object, position: object, orientation: object, jpeg: bytes) -> Outcome:
        """Store the frame if it passes the rules; the outcome says why not otherwise."""
        try:
            pose, repaired = Pose.parse(ts, position, orientation)
        except InvalidPose as exc:
            return self._drop(Outcome.BAD_POSE, f"bad pose: {exc}")
        if len(self) and pose.ts < self._ts[self._end - 1]:
            return self._drop(
                Outcome.OUT_OF_ORDER,
                f"frame at {pose.ts} is older than the newest stored ({self._ts[self._end - 1]})",
            )
        if len(self) and not self._far_enough(pose):
            self.stats.too_close += 1
            return Outcome.TOO_CLOSE
        # Checked last: decoding costs about a millisecond, wasted on frames not kept.
        if not is_valid_jpeg(jpeg, decode=self.decode_jpeg):
            return self._drop(Outcome.CORRUPT_JPEG, "corrupt JPEG")
        if repaired:
            self.stats.repaired_quaternions += 1
        self._append(pose, bytes(jpeg))
        return Outcome.STORED

    def _drop(self, outcome: Outcome, reason: str) -> Outcome:
        counter = outcome.value
        setattr(self.stats, counter, getattr(self.stats, counter) + 1)
        log.info("frame dropped: %s", reason)
        return outcome

    def _far_enough(self, pose: Pose) -> bool:
        last = self._end - 1
        moved = float(np.linalg.norm(pose.position - self._positions[last]))
        if moved >= self.min_distance_m:
            return True
        turned = abs(
            math.remainder(float(yaw(pose.orientation) - yaw(self._orientations[last])), math.tau)
        )
        return math.degrees(turned) >= self.min_yaw_deg

    def _append(self, pose: Pose, jpeg: bytes) -> None:
        if self._end == len(self._ts):
            self._compact()
        i = self._end
        self._ids[i] = self._next_id
        self._ts[i] = pose.ts
        self._positions[i] = pose.position
        self._orientations[i] = pose.orientation
        inverse, anchor, left = FrameSet.derive(pose.position, pose.orientation)
        self._inverse_rotations[i] = inverse
        self._anchors[i] = anchor
        self._inverse_left[i] = left
        self._jpegs[i] = jpeg
        self._next_id += 1
        self._end += 1
        self.stats.stored += 1
        if len(self) > self.capacity:
            self._jpegs[self._start] = None
            self._start += 1
            self.stats.evicted += 1

    def _compact(self) -> None:
        n = len(self)
        live = slice(self._start, self._end)
        for array in (
            self._ids,
            self._ts,
            self._positions,
            self._orientations,
            self._inverse_rotations,
            self._anchors,
            self._inverse_left,
        ):
            array[:n] = array[live].copy()
        self._jpegs[:n] = self._jpegs[live]
        self._jpegs[n:] = [None] * (len(self._jpegs) - n)
        self._start, self._end = 0, n

    def frames(self) -> FrameSet:
        """The stored frames, oldest first, as views into the buffer.

        Valid until the next ``add``: use it right away, do not keep it.
        """
        live = slice(self._start, self._end)
        return FrameSet(
            self._ids[live],
            self._ts[live],
            self._positions[live],
            self._orientations[live],
            self._inverse_rotations[live],
            self._anchors[live],
            self._inverse_left[live],
        )

    def frame_at(self, index: int) -> Frame:
        """The frame at chronological index (0 is the oldest, -1 the newest)."""
        n = len(self)
        if not -n <= index < n:
            raise IndexError(f"frame index {index} out of range for {n} frames")
        i = self._start + (index % n)
        pose = Pose(float(self._ts[i]), self._positions[i].copy(), self._orientations[i].copy())
        jpeg = self._jpegs[i]
        assert jpeg is not None  # every live slot holds its image
        return Frame(int(self._ids[i]), pose, jpeg)

    def get(self, frame_id: int) -> Frame | None:
        """The stored frame with that id, or None once it has been evicted."""
        if not len(self):
            return None
        # Stored ids are consecutive, so the position follows from the oldest one.
        index = frame_id - int(self._ids[self._start])
        return self.frame_at(index) if 0 <= index < len(self) else None
