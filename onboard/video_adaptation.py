"""Live video's bitrate and resolution follow what the link carries.

Two measures of the link reach the publisher: the receiver's estimate of the bitrate the
path carries ([REMB], sent by the media server's receiver about once a second), and the
round trip of its RTCP reports (RFC 3550 section 6.4.1), which grows with the packets
queued on the path; the queue is the round trip less the least seen in the session.
The estimate alone is not trusted to narrow the picture: aiortc's estimator is
delay-based, and on a busy computer processing jitter reads as queueing, after which it
climbs back only slowly; a picture that followed it would shrink on an open link. The
round trip tells a queue on the link from jitter at the ends.

The rule:

- **Narrow link**: the link is narrow from the first round trip that exceeds the least
  seen in the session by ``QUEUE_EVIDENCE_S`` (0.2 s: packets are queueing on the path),
  until the estimate has stayed at or above ``WIDE_FLOOR_BPS`` for ``UP_HOLD_S``. Round
  trips count from the first estimate on: before it the session is still starting, and
  its first reports wait for that. At once, not after a wait: a link's buffer fills
  within a second or two, and once it is full every packet behind it (MQTT's too) waits
  its length and the video's are dropped. The cost: a computer so busy that its own
  round trips stall by 0.2 s narrows the picture as a queueing link would.
- **Pause**: while a round trip shows more than ``PAUSE_QUEUE_S`` (0.5 s) queued, no
  frame is sent for as long as the queue it shows: a frame sent then would reach the
  ground later than teleoperation's bound anyway (docs/video.md), and would only hold
  back the commands' answers and telemetry queued with it. The link's buffer drains at
  all the link carries beyond MQTT, not at the little the video leaves.
- **The uplink's own queue**: the agent's MQTT connection crosses the same link, and the
  kernel knows how long its oldest unacknowledged byte has waited (onboard/live_video.py
  reads it every 50 ms, ``uplink_wait_s``). Less the least round trip the connection
  has seen, that is the link's queue, measured a sample period after it forms rather
  than a report interval (about a second) after. The link is narrow once it exceeds
  ``QUEUE_EVIDENCE_S``, as with a round trip; and while it exceeds
  ``UPLINK_PAUSE_QUEUE_S`` no frame is sent (a pause ends ``UPLINK_PAUSE_HOLD_S`` after
  the last sample over the bound). 0.1 s, lower than the round trips' 0.5 s: the measure
  lags the queue by the queue's own length (the byte it dates waited that long), and
  while it lags the video fills the link, so the real queue when a pause starts is
  about twice the bound. Measured on a kernel-shaped 80 kbit/s link with a 2 s buffer
  (tests/livevideo/test_kernel_link.py), commands' round trips in a narrowing's first
  4 s peaked at 0.69–1.04 s with a bound of 0.2 s (5 runs) and 0.36–0.57 s with 0.1 s
  (9 runs). Below 0.1 s a link's own jitter would pause the picture; on that link's
  open phase the measure stayed under 0.05 s.
- **Bitrate**: the encoder's target is the estimate, at most 1.5 Mbit/s and at least
  ``WIDE_FLOOR_BPS`` (250 kbit/s, aiortc's own floor) on a link not known to be narrow,
  ``MIN_TARGET_BPS`` (30 kbit/s) on a narrow one: there the picture gets coarser rather
  than the link fuller.
- **Resolution**: a ladder of the configured size, then each half of it down to
  ``MIN_RUNG_WIDTH`` pixels wide (640 x 480 → 320 x 240 → 160 x 120). A size needs
  ``NEED_BITS_PER_PIXEL`` (0.07) bits per pixel per frame, the low-motion figure of the
  Kush gauge ([Kush gauge]): at 15 frames per second 640 x 480 needs 323 kbit/s,
  320 x 240 81 kbit/s, 160 x 120 20 kbit/s. On a narrow link the picture steps down one
  size when the estimate has stayed below what the current size needs for
  ``DOWN_HOLD_S`` (1 s). It steps up one size when the estimate has stayed at or above
  ``UP_FACTOR`` (2) times what the larger size needs for ``UP_HOLD_S`` (5 s); the factor
  and the wait are the hysteresis that keeps a link near a threshold from making the
  picture flap. The smallest size stays whatever the estimate.
- **Retransmissions** (onboard/live_video.py): a lost packet is re-sent once at most,
  and one asked for during a pause when the pause ends.
- **Keyframes**: a receiver that lost packets asks for a keyframe (RTCP PLI); on a
  congested link every keyframe loses packets again, and keyframes sent at every request
  fill the link with keyframes. A request is honoured once the previous keyframe has had
  the time to cross the link at ``KEYFRAME_SHARE`` (half) of the estimate, and never
  within ``MIN_KEYFRAME_INTERVAL_S`` (300 ms) of it.

Plain functions of the measures and the time, without I/O: ``onboard/live_video.py``
feeds them every estimate and round trip it receives and renders the size they choose.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, replace

NEED_BITS_PER_PIXEL = 0.07
UP_FACTOR = 2.0
DOWN_HOLD_S = 1.0
UP_HOLD_S = 5.0
MIN_RUNG_WIDTH = 160
MIN_RUNG_HEIGHT = 90
MIN_TARGET_BPS = 30_000
WIDE_FLOOR_BPS = 250_000
QUEUE_EVIDENCE_S = 0.2
PAUSE_QUEUE_S = 0.5
UPLINK_PAUSE_QUEUE_S = 0.1
# Two of the agent's 50 ms samples and a late one: a pause outlives a sample that is late.
UPLINK_PAUSE_HOLD_S = 0.15
# libwebrtc honours a keyframe request at most every 300 ms ([libwebrtc encoder feedback]).
MIN_KEYFRAME_INTERVAL_S = 0.3
KEYFRAME_SHARE = 0.5


@dataclass(frozen=True)
class Size:
    width: int
    height: int

    def __str__(self) -> str:
        return f"{self.width}x{self.height}"


def ladder(width: int, height: int) -> tuple[Size, ...]:
    """The sizes to choose from, largest first: the configured size, then each half of it
    while the half is at least MIN_RUNG_WIDTH x MIN_RUNG_HEIGHT and of even sides."""
    sizes = [Size(width, height)]
    while True:
        w, h = sizes[-1].width // 2, sizes[-1].height // 2
        if w < MIN_RUNG_WIDTH or h < MIN_RUNG_HEIGHT or w % 2 or h % 2:
            return tuple(sizes)
        sizes.append(Size(w, h))


def need_bps(size: Size, fps: float) -> float:
    """The bitrate a picture of `size` at `fps` frames per second needs ([Kush gauge],
    low motion)."""
    return size.width * size.height * fps * NEED_BITS_PER_PIXEL


@dataclass(frozen=True)
class Adaptation:
    """Where on the ladder the picture is (0 = the largest size), since when the estimate
    has been below the current size's need or above the larger one's bar, whether the
    link is narrow (and since when the estimate says it is wide again), and the least
    round trip seen."""

    rung: int = 0
    low_since: float | None = None
    high_since: float | None = None
    narrow: bool = False
    wide_since: float | None = None
    least_rtt_s: float | None = None
    queue_s: float = 0.0


def _since(flag: bool, since: float | None, now: float) -> float | None:
    """When a condition that holds now began (`since`, or now), None when it does not."""
    return (since if since is not None else now) if flag else None


def report_round_trip_s(sent_at: float, dlsr: int, now: float) -> float:
    """The round trip a receiver report gives (RFC 3550 section 6.4.1): the time since the
    sender report it answers was sent (`sent_at`), less the receiver's delay since that
    report (DLSR, in 1/65536 s)."""
    return now - sent_at - dlsr / 65536


def pause_s(state: Adaptation) -> float:
    """How long to send no frame: the queue's length when it exceeds PAUSE_QUEUE_S."""
    return state.queue_s if state.queue_s > PAUSE_QUEUE_S else 0.0


def observe_rtt(state: Adaptation, rtt_s: float) -> Adaptation:
    """The state after a round trip of `rtt_s`: the queue it shows (the round trip less
    the least seen), narrow once that exceeds QUEUE_EVIDENCE_S."""
    least = rtt_s if state.least_rtt_s is None else min(state.least_rtt_s, rtt_s)
    queue = rtt_s - least
    if queue > QUEUE_EVIDENCE_S:
        return replace(state, narrow=True, wide_since=None, least_rtt_s=least, queue_s=queue)
    return replace(state, least_rtt_s=least, queue_s=queue)


def uplink_wait_s(written: Iterable[tuple[float, int]], acked: int, now: float) -> float:
    """How long the oldest byte of a TCP connection not yet acknowledged has waited, at
    least: `written` holds (time, bytes written so far) samples oldest first, `acked` the
    bytes acknowledged now. That byte was written after the last sample short of it and by
    the first past it: it has waited since then. 0 when every written byte is acknowledged."""
    for at, total in written:
        if total > acked:
            return now - at
    return 0.0


def observe_uplink_queue(state: Adaptation, queue_s: float) -> Adaptation:
    """The state after the uplink's own queue was measured at `queue_s` (the agent's MQTT
    connection's oldest unacknowledged byte's wait less its least round trip): narrow once
    it exceeds QUEUE_EVIDENCE_S."""
    if queue_s > QUEUE_EVIDENCE_S:
        return replace(state, narrow=True, wide_since=None)
    return state


def uplink_pause_s(queue_s: float) -> float:
    """How long to send no frame after the uplink's queue was measured at `queue_s`:
    UPLINK_PAUSE_HOLD_S while it exceeds UPLINK_PAUSE_QUEUE_S, so the pause lasts until
    the samples show the queue under the bound."""
    return UPLINK_PAUSE_HOLD_S if queue_s > UPLINK_PAUSE_QUEUE_S else 0.0


def decide(
    state: Adaptation, sizes: tuple[Size, ...], fps: float, estimate_bps: float, now: float
) -> Adaptation:
    """The state after an estimate of `estimate_bps` received at `now` (seconds)."""
    narrow, wide_since = state.narrow, _since(estimate_bps >= WIDE_FLOOR_BPS, state.wide_since, now)
    if narrow and wide_since is not None and now - wide_since >= UP_HOLD_S:
        narrow, wide_since = False, None
    low = narrow and estimate_bps < need_bps(sizes[state.rung], fps)
    high = state.rung > 0 and estimate_bps >= UP_FACTOR * need_bps(sizes[state.rung - 1], fps)
    low_since = _since(low, state.low_since, now)
    high_since = _since(high, state.high_since, now)
    rung = state.rung
    if low_since is not None and now - low_since >= DOWN_HOLD_S and rung < len(sizes) - 1:
        rung, low_since, high_since = rung + 1, None, None
    elif high_since is not None and now - high_since >= UP_HOLD_S:
        rung, low_since, high_since = rung - 1, None, None
    return replace(
        state,
        rung=rung,
        low_since=low_since,
        high_since=high_since,
        narrow=narrow,
        wide_since=wide_since if narrow else None,
    )


def encoder_target_bps(estimate_bps: float, max_bps: int, *, narrow: bool) -> int:
    """The encoder's target for an estimate: the estimate, within max_bps and the floor
    of the link (MIN_TARGET_BPS when narrow, else WIDE_FLOOR_BPS)."""
    floor = MIN_TARGET_BPS if narrow else WIDE_FLOOR_BPS
    return int(max(floor, min(estimate_bps, max_bps)))


def keyframe_due(last_at: float | None, last_bytes: int, estimate_bps: float, now: float) -> bool:
    """Whether a keyframe asked for at `now` is sent: not before the previous one (sent
    at `last_at`, `last_bytes` long) had the time to cross the link at KEYFRAME_SHARE of
    the estimate, nor within MIN_KEYFRAME_INTERVAL_S of it."""
    if last_at is None:
        return True
    crossing = last_bytes * 8 / (KEYFRAME_SHARE * max(estimate_bps, MIN_TARGET_BPS))
    return now - last_at >= max(MIN_KEYFRAME_INTERVAL_S, crossing)
