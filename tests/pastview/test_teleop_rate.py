"""Teleoperation over the past-view socket is rate-limited per user (TELEOP_RATE,
config/throttling.py): past the limit a move is answered with a refusal and the socket
stays open; a stop always gets through."""

from __future__ import annotations

import pytest

from .support import in_own_loop
from .test_consumer import connect

pytestmark = [
    pytest.mark.django_db(transaction=True),
    pytest.mark.usefixtures("no_snapshots_from_earlier_tests"),
]

MOVE_OUT_OF_RANGE = {"type": "teleop", "forward": 3, "right": 0, "up": 0}


@in_own_loop
async def test_moves_past_the_limit_are_refused_and_the_socket_stays_open(world_tx, settings):
    settings.TELEOP_RATE = "3/min"  # per minute: the test does not depend on its speed
    communicator, connected, _ = await connect(world_tx.operator)
    try:
        assert connected
        await communicator.receive_json_from(timeout=5)
        for _ in range(3):  # counted, then answered by the ordinary checks
            await communicator.send_json_to(MOVE_OUT_OF_RANGE)
            assert "within -1..1" in (await communicator.receive_json_from(5))["error"]
        await communicator.send_json_to(MOVE_OUT_OF_RANGE)
        refused = await communicator.receive_json_from(5)
        assert refused["ok"] is False and refused["error"].startswith("Too many moves")
        await communicator.send_json_to({"type": "stop"})  # not limited, and not answered
        await communicator.send_json_to(["not", "a", "move"])
        assert (await communicator.receive_json_from(5))["error"] == "Unknown message type."
    finally:
        await communicator.disconnect()
