"""A drone on a link the kernel shapes: the simulated drone's agent runs in a network
namespace whose only way out is a veth pair, its egress an HTB class over a first-in
first-out buffer of about 2 s (tests/support/netns_link.py) — a dumb radio modem's, the
worst case. Its MQTT connection and its live video cross it to the broker and the media
server on the host. Unlike the userspace relay of test_throttled_link.py, the agent's TCP
acknowledgements come back through the link, so its kernel sees the link's queue in its
MQTT connection (onboard/live_video.py UplinkProbe), and the video stops filling the
buffer within a sample of the narrowing rather than a receiver report's second.

SKYHIVE_COMPARE_UPLINK=1 also runs the agent with that measure off
(SKYHIVE_LIVE_VIDEO_UPLINK_QUEUE=off, the RTCP round trips alone), and asserts that it
breaks the bound the measure keeps; and the link's buffer as fq_codel (Linux's default
queue discipline, its flows isolated) where the kernel has it.
"""

from __future__ import annotations

import os
import statistics
import time
from pathlib import Path

import pytest

from firmware.sim import start_simulator
from firmware.sim.fleet import agent_process, copy_gear
from fleet.models import Drone
from onboard.live_video import UPLINK_ENV
from tests.onboard.ground import Ground
from tests.support.netns_link import Forwarder, NetnsLink, available
from workers.broker.credentials import stored_hash
from workers.mosquitto import start_broker

from .support import MediaServer, wait_until

# Real time: a command's round trip is held to a bound measured with a core to spare.
pytestmark = [pytest.mark.e2e, pytest.mark.realtime, pytest.mark.django_db(transaction=True)]

DRONE = "ACME_1"
PASSWORD = "acme-one-password"
HOME = (40.6303, -8.6575, 12.0)
FPS = 10
NARROW_BPS = 80_000  # room for the smallest picture at the encoder's floor beside MQTT
BUFFER_S = 2.0  # the modem's buffer, at the narrow rate
ONSET_S = 4.0  # the narrowing's first seconds, before the RTCP round trips tell
OPEN_S = 3.0
# The most a command's round trip takes in the narrowing's first 4 s with the measure on.
# Measured on the 2-core development machine: with it on, 0.36–0.57 s at most (median
# 0.13–0.29 s, 9 runs); with it off, 2.5–10.3 s at most (median 0.25–0.74 s, 6 runs: the
# buffer filled before a receiver report told). The bound is twice the first's worst and
# half the second's best.
ONSET_BOUND_S = 1.2

COMPARE = os.environ.get("SKYHIVE_COMPARE_UPLINK") == "1"
compare_only = pytest.mark.skipif(not COMPARE, reason="a comparison: SKYHIVE_COMPARE_UPLINK=1")


@pytest.fixture
def kernel_link(world_tx, tmp_path: Path):  # type: ignore[no-untyped-def]
    """A function starting the drone in its namespace with the uplink measure on or off;
    it returns the namespace, the media server, the ground's MQTT client."""
    from django.db import connection

    reason = available()
    if reason is not None:
        pytest.skip(reason)
    Drone.objects.filter(drone_id=DRONE).update(mqtt_password_hash=stored_hash(PASSWORD))
    closing: list = []

    def start(uplink_queue: str):  # type: ignore[no-untyped-def]
        link = NetnsLink()
        closing.append(link)
        media = MediaServer(connection.settings_dict["NAME"])
        closing.append(media)
        broker = start_broker(tmp_path / "broker", {"ground": "pw", DRONE: PASSWORD})
        closing.append(broker)
        mqtt = Forwarder(link.host_address, broker.port)
        whip = Forwarder(link.host_address, int(media.drone_url.rsplit(":", 1)[1]))
        closing.extend([mqtt, whip])
        sim = start_simulator(home=HOME, time_scale=1.0, arming_line=tmp_path / "arming_line",
                              log_file=tmp_path / "sim.log")  # fmt: skip
        closing.append(sim)
        copy_gear(tmp_path)
        agent = agent_process(
            DRONE,
            tmp_path,
            sim.url,
            f"mqtt://{DRONE}:{PASSWORD}@{link.host_address}:{mqtt.port}",
            arming_line=tmp_path / "arming_line",
            extra=["--heartbeat-interval", "0.5",
                   "--media-url", f"http://{link.host_address}:{whip.port}",
                   "--live-fps", str(FPS)],
        )  # fmt: skip
        agent.argv = link.wrap(list(agent.argv))
        agent.env = {**(agent.env or os.environ), UPLINK_ENV: uplink_queue}
        closing.append(agent.start())
        ground = Ground(broker.port, DRONE)
        closing.append(ground)
        wait_until(lambda: media.get(f"/streams/{DRONE}").get("frames", 0) > 3, 60)
        return link, media, ground

    yield start
    for thing in reversed(closing):
        try:
            thing.close() if isinstance(thing, (Ground, NetnsLink, Forwarder)) else thing.stop()
        except Exception:  # noqa: BLE001 - the rest are closed all the same
            pass


def command_round_trip(ground: Ground) -> float:
    asked = time.monotonic()
    assert ground.command("objrequest", timeout=20, value="FlightStatus")["ok"]
    return time.monotonic() - asked


def onset_round_trips(link: NetnsLink, ground: Ground, queue: str = "bfifo") -> list[float]:
    """The command round trips of the narrowing's first ONSET_S, after OPEN_S open."""
    opened = time.monotonic()
    open_rtts = [command_round_trip(ground)]
    while time.monotonic() - opened < OPEN_S:
        open_rtts.append(command_round_trip(ground))
    link.shape(NARROW_BPS, BUFFER_S, queue=queue)
    narrowed = time.monotonic()
    rtts = []
    while time.monotonic() - narrowed < ONSET_S:
        rtts.append(command_round_trip(ground))
    print(f"open round trips max {max(open_rtts):.3f} s; onset ({queue}) "
          f"{[round(r, 3) for r in rtts]} median {statistics.median(rtts):.3f} s "
          f"max {max(rtts):.3f} s\n{link.stats()}")  # fmt: skip
    return rtts


def test_commands_cross_a_narrowing_kernel_link_within_the_bound(kernel_link):  # type: ignore[no-untyped-def]
    link, media, ground = kernel_link("on")
    rtts = onset_round_trips(link, ground)
    assert max(rtts) < ONSET_BOUND_S, rtts


@compare_only
def test_without_the_uplink_measure_commands_wait_longer(kernel_link):  # type: ignore[no-untyped-def]
    link, media, ground = kernel_link("off")
    rtts = onset_round_trips(link, ground)
    assert max(rtts) >= ONSET_BOUND_S, rtts


@compare_only
def test_fq_codel_keeps_commands_out_of_the_videos_queue(kernel_link):  # type: ignore[no-untyped-def]
    link, media, ground = kernel_link("off")
    try:
        link.shape(1_000_000, BUFFER_S, queue="fq_codel")
    except OSError as exc:
        pytest.skip(f"no fq_codel in this kernel ({exc})")
    rtts = onset_round_trips(link, ground, queue="fq_codel")
    assert max(rtts) < ONSET_BOUND_S, rtts
