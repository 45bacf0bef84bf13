"""The uplink's own queue, measured by the agent on its MQTT connection (the kernel's
counts of it), as a second measure of the link beside the RTCP round trips
(onboard/video_adaptation.py, onboard/live_video.py UplinkProbe)."""

from __future__ import annotations

import io
import json
import signal
import socket
import time

import pytest

from onboard.live_video import LatestPose, UplinkProbe
from onboard.video_adaptation import (
    QUEUE_EVIDENCE_S,
    UPLINK_PAUSE_HOLD_S,
    UPLINK_PAUSE_QUEUE_S,
    Adaptation,
    observe_uplink_queue,
    uplink_pause_s,
    uplink_wait_s,
)


def test_the_oldest_unacknowledged_byte_waited_since_the_first_sample_that_wrote_it():
    written = [(10.0, 100), (10.05, 300), (10.1, 300), (10.15, 900)]
    assert uplink_wait_s(written, 100, 10.2) == pytest.approx(0.15)  # byte 100: by 10.05
    assert uplink_wait_s(written, 299, 10.2) == pytest.approx(0.15)
    assert uplink_wait_s(written, 300, 10.2) == pytest.approx(0.05)
    assert uplink_wait_s(written, 900, 10.2) == 0.0  # everything acknowledged


def test_a_queue_over_200_ms_narrows_the_link_and_one_over_100_ms_pauses_the_video():
    assert not observe_uplink_queue(Adaptation(), QUEUE_EVIDENCE_S).narrow
    assert observe_uplink_queue(Adaptation(), QUEUE_EVIDENCE_S + 0.01).narrow
    assert uplink_pause_s(UPLINK_PAUSE_QUEUE_S) == 0.0
    assert uplink_pause_s(UPLINK_PAUSE_QUEUE_S + 0.01) == UPLINK_PAUSE_HOLD_S


def read_lines(lines: list[str]) -> tuple[LatestPose, list[float]]:
    """What the child's reading thread makes of `lines` (at their end it ends the child
    with SIGTERM: caught here)."""
    poses, queues = LatestPose(), []
    poses.on_uplink_queue = queues.append
    previous = signal.signal(signal.SIGTERM, lambda *_: None)
    try:
        poses.read_forever(io.StringIO("".join(line + "\n" for line in lines)))
    finally:
        signal.signal(signal.SIGTERM, previous)
    return poses, queues


def test_an_older_child_skips_the_queue_line_and_a_newer_one_reads_both():
    queue_line, pose_line = json.dumps({"queue_s": 0.4}), json.dumps([1, 2, 3, 0, 0, 0, 1])
    # An older child's parse of a line: seven numbers, or the line is skipped.
    with pytest.raises(ValueError):
        n, e, d, qx, qy, qz, qw = (float(v) for v in json.loads(queue_line))
    poses, queues = read_lines([queue_line, pose_line])
    assert queues == [0.4]
    assert poses.value == ((1.0, 2.0, 3.0), (0.0, 0.0, 0.0, 1.0))


@pytest.mark.skipif(not hasattr(socket, "TCP_INFO"), reason="TCP_INFO is Linux's")
def test_the_probe_reads_a_real_connections_unacknowledged_wait():
    """A peer that stops reading: its receive window fills, the sender's bytes stay
    unacknowledged, and the probe's queue grows with the time they have waited."""
    server = socket.create_server(("127.0.0.1", 0))
    sender = socket.create_connection(server.getsockname())
    receiver, _ = server.accept()
    receiver.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    probe = UplinkProbe(lambda: sender)
    try:
        assert probe.queue_s(time.monotonic()) == 0.0  # nothing written
        sender.setblocking(False)
        deadline = time.monotonic() + 10
        queued = 0.0
        while queued < 0.3 and time.monotonic() < deadline:
            try:
                sender.send(b"x" * 65536)
            except BlockingIOError:
                pass
            time.sleep(0.05)
            queued = probe.queue_s(time.monotonic()) or 0.0
        assert queued >= 0.3
        # The peer reads again: everything is acknowledged, and the queue is gone.
        receiver.setblocking(False)
        while probe.queue_s(time.monotonic()) != 0.0 and time.monotonic() < deadline + 10:
            try:
                receiver.recv(1 << 20)
            except BlockingIOError:
                time.sleep(0.01)
        assert probe.queue_s(time.monotonic()) == 0.0
    finally:
        for sock in (sender, receiver, server):
            sock.close()


def test_no_socket_no_measure():
    assert UplinkProbe(lambda: None).queue_s(time.monotonic()) is None
    udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        assert UplinkProbe(lambda: udp).queue_s(time.monotonic()) is None
    finally:
        udp.close()
