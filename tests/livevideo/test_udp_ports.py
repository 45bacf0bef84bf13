"""The media server's UDP ports within a configured range (livevideo/ports.py): the
range's parsing, a real event loop's binds, and the ICE candidates of a real media
server's answer."""

from __future__ import annotations

import asyncio
import re
import socket

import pytest

from livevideo.ports import PortRange, PortRangeError, confine_udp, parse_port_range


def test_a_range_is_first_dash_last_within_the_unprivileged_ports():
    assert parse_port_range("40000-40099") == PortRange(40000, 40099)
    assert parse_port_range(" 40000 - 40000 ") == PortRange(40000, 40000)
    assert parse_port_range("") is None
    for bad in ("40000", "40099-40000", "80-90", "40000-70000", "a-b", "40000:40099"):
        with pytest.raises(PortRangeError):
            parse_port_range(bad)


def test_the_ports_are_tried_from_a_start_round_the_range():
    assert PortRange(10000, 10004).ports_from(10003) == [10003, 10004, 10000, 10001, 10002]
    assert len(PortRange(10000, 10004)) == 5 and 10004 in PortRange(10000, 10004)


def _free_range(size: int) -> PortRange:
    """A range of `size` ports that were all free a moment ago."""
    for first in range(41000, 60000, size):
        held = []
        try:
            for port in range(first, first + size):
                sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
                held.append(sock)
                sock.bind(("127.0.0.1", port))
            return PortRange(first, first + size - 1)
        except OSError:
            continue
        finally:
            for sock in held:
                sock.close()
    raise AssertionError("no free range")


def test_a_confined_loop_binds_port_zero_within_the_range_until_it_is_full():
    ports = _free_range(3)

    async def bind_all() -> tuple[list[int], OSError | None]:
        loop = asyncio.get_running_loop()
        confine_udp(loop, ports)
        transports, bound, refused = [], [], None
        try:
            for _ in range(4):
                try:
                    transport, _ = await loop.create_datagram_endpoint(
                        asyncio.DatagramProtocol, local_addr=("127.0.0.1", 0)
                    )
                except OSError as exc:
                    refused = exc
                    continue
                transports.append(transport)
                bound.append(transport.get_extra_info("sockname")[1])
        finally:
            for transport in transports:
                transport.close()
        return bound, refused

    bound, refused = asyncio.run(bind_all())
    assert sorted(bound) == list(range(ports.first, ports.last + 1))
    assert refused is not None and "no free UDP port" in str(refused)


@pytest.mark.e2e
@pytest.mark.django_db(transaction=True)
def test_the_media_servers_candidates_lie_in_its_range(world_tx):  # type: ignore[no-untyped-def]
    from onboard.live_video import basic_auth

    drone = world_tx.drone
    ports = _free_range(20)
    media = _media_server_for(drone, ports)
    try:
        answers = [_answer(media, drone.drone_id, basic_auth) for _ in range(2)]
    finally:
        media.stop()
    candidates = [
        (m["ip"], int(m["port"]))
        for answer in answers
        for m in re.finditer(r"a=candidate:\S+ \d+ udp \d+ (?P<ip>\S+) (?P<port>\d+) typ", answer)
    ]
    assert candidates, answers
    assert all(port in ports for _, port in candidates), candidates
    # Each session its own ports: the second publish replaced the first, on other ports.
    assert len({c for c in candidates}) == len(candidates)


@pytest.mark.e2e
@pytest.mark.django_db(transaction=True)
def test_a_full_range_refuses_the_session_saying_why(world_tx):  # type: ignore[no-untyped-def]
    from onboard.live_video import basic_auth

    drone = world_tx.drone
    ports, taken = _held_range(2)
    media = _media_server_for(drone, ports)
    try:
        status, body = _offer(media, drone.drone_id, basic_auth)
        counts = media.get("/health")["counts"]
    finally:
        media.stop()
        for sock in taken:
            sock.close()
    assert status == 503 and b"no_media_port" in body, (status, body)
    assert counts.get("refused_no_media_port") == 1, counts
    assert not counts.get("published"), counts


def _media_server_for(drone, ports: PortRange):  # type: ignore[no-untyped-def]
    """A media server confined to `ports` that knows `drone` by the password
    "drone-password"."""
    from django.db import connection

    from workers.broker.credentials import stored_hash

    from .support import MediaServer

    drone.mqtt_password_hash = stored_hash("drone-password")
    drone.save(update_fields=["mqtt_password_hash"])
    return MediaServer(
        connection.settings_dict["NAME"], LIVE_VIDEO_UDP_PORTS=f"{ports.first}-{ports.last}"
    )


def _held_range(size: int) -> tuple[PortRange, list[socket.socket]]:
    """A range of `size` ports and UDP sockets holding each of them on every address."""
    for first in range(43000, 60000, size):
        held: list[socket.socket] = []
        try:
            for port in range(first, first + size):
                held.append(_wildcard_udp(port))
            return PortRange(first, first + size - 1), held
        except OSError:
            for sock in held:
                sock.close()
    raise AssertionError("no free range")


def _wildcard_udp(port: int) -> socket.socket:
    """A UDP socket on `port` of every address (IPv6 and IPv4 where the host has both)."""
    sock = socket.socket(socket.AF_INET6 if socket.has_ipv6 else socket.AF_INET, socket.SOCK_DGRAM)
    try:
        if sock.family == socket.AF_INET6:
            sock.setsockopt(socket.IPPROTO_IPV6, socket.IPV6_V6ONLY, 0)
            sock.bind(("::", port))
        else:
            sock.bind(("0.0.0.0", port))
    except OSError:
        sock.close()
        raise
    return sock


def _answer(media, drone_id: str, basic_auth) -> str:  # type: ignore[no-untyped-def]
    """The media server's SDP answer to a real aiortc offer of one video stream."""
    status, body = _offer(media, drone_id, basic_auth)
    assert status == 201, body
    return body.decode()


def _offer(media, drone_id: str, basic_auth) -> tuple[int, bytes]:  # type: ignore[no-untyped-def]
    """The media server's status and body for a real aiortc offer of one video stream."""
    from aiortc import RTCPeerConnection

    from .support import post

    async def offer() -> str:
        pc = RTCPeerConnection()
        pc.addTransceiver("video", direction="sendonly")
        await pc.setLocalDescription(await pc.createOffer())
        sdp = pc.localDescription.sdp
        await pc.close()
        return sdp

    return post(
        f"{media.drone_url}/whip/{drone_id}",
        asyncio.run(offer()).encode(),
        {
            "Content-Type": "application/sdp",
            "Authorization": basic_auth(drone_id, "drone-password"),
        },
    )
