"""The media server's media ports: every UDP socket it opens (one per WebRTC session and
network interface, for ICE and the media, [RFC 8445] host candidates) binds within a
configured range, so a firewall in front of it opens that range and nothing else.

aiortc (through aioice) binds its sockets to port 0, an ephemeral port anywhere. With a
range set (``LIVE_VIDEO_UDP_PORTS``, "first-last"), the media server's event loop binds
each such socket to a free port of the range instead, trying them from a random one
onward; when every port of the range is taken the bind fails (``OSError``), aioice
leaves that interface out and the session gets no candidate there.
"""

from __future__ import annotations

import asyncio
import errno
import random
from dataclasses import dataclass
from typing import Any


class PortRangeError(ValueError):
    pass


@dataclass(frozen=True)
class PortRange:
    first: int
    last: int

    def __post_init__(self) -> None:
        if not 1024 <= self.first <= self.last <= 65535:
            raise PortRangeError(
                f"a UDP port range is first-last within 1024..65535, got {self.first}-{self.last}"
            )

    def __contains__(self, port: object) -> bool:
        return isinstance(port, int) and self.first <= port <= self.last

    def __len__(self) -> int:
        return self.last - self.first + 1

    def ports_from(self, start: int) -> list[int]:
        """Every port of the range, from `start` on and round to the one before it."""
        offset = (start - self.first) % len(self)
        ports = list(range(self.first, self.last + 1))
        return ports[offset:] + ports[:offset]


def parse_port_range(text: str) -> PortRange | None:
    """ "first-last" as a PortRange; None for an empty text (ephemeral ports)."""
    text = text.strip()
    if not text:
        return None
    first, sep, last = text.partition("-")
    if not sep or not first.strip().isdigit() or not last.strip().isdigit():
        raise PortRangeError(f"a UDP port range is written first-last, got {text!r}")
    return PortRange(int(first), int(last))


def confine_udp(loop: asyncio.AbstractEventLoop, ports: PortRange) -> None:
    """Make `loop` bind every UDP endpoint asked for on port 0 to a free port of `ports`."""
    create = loop.create_datagram_endpoint

    async def create_in_range(protocol_factory, local_addr=None, **kwargs: Any):  # type: ignore[no-untyped-def]
        if local_addr is None or local_addr[1] != 0:
            return await create(protocol_factory, local_addr=local_addr, **kwargs)
        host = local_addr[0]
        for port in ports.ports_from(random.randint(ports.first, ports.last)):
            try:
                return await create(protocol_factory, local_addr=(host, port), **kwargs)
            except OSError as exc:
                if exc.errno != errno.EADDRINUSE:
                    raise
        raise OSError(errno.EADDRINUSE, f"no free UDP port in {ports.first}-{ports.last}")

    loop.create_datagram_endpoint = create_in_range  # type: ignore[method-assign]
