"""Links to a flight controller, named by URL.

- `serial:/dev/ttyACM0?baud=115200` (or `serial:///dev/ttyACM0`), or a bare path such as
  `/dev/pts/5`: a serial port or pseudo-terminal through pyserial, opened exclusively so
  no second session can share the line;
- `tcp://host:9000`: dRonin's own Linux firmware build (flightd) or the simulator's --tcp.

Every link has `read(max_bytes, timeout) -> bytes`, `write(data)` and `close()`; they
raise `LinkDown` when the line has vanished. `ReopeningLink` wraps a URL and reopens it.
"""

from __future__ import annotations

import contextlib
import logging
import select
import socket
import threading
import time
from dataclasses import dataclass
from typing import Protocol
from urllib.parse import parse_qs, urlsplit

log = logging.getLogger(__name__)

DEFAULT_BAUD = 115200


class LinkError(OSError):
    """A link URL that cannot be used."""


class LinkDown(LinkError):
    """The line is gone (device unplugged, simulator stopped, socket closed)."""


class Link(Protocol):
    url: str

    def read(self, max_bytes: int = 4096, timeout: float = 0.1) -> bytes: ...

    def write(self, data: bytes) -> None: ...

    def close(self) -> None: ...


@dataclass(frozen=True)
class LinkSpec:
    kind: str  # "serial", "tcp" or "udp"
    path: str = ""
    baud: int = DEFAULT_BAUD
    host: str = ""
    port: int = 0


def parse_link_url(url: str) -> LinkSpec:
    """Split a link URL into its parts; raise LinkError with the reason when it is not one."""
    text = url.strip()
    if text.startswith("/"):
        return LinkSpec("serial", path=text)
    parts = urlsplit(text)
    if parts.scheme == "serial":
        path = parts.path or parts.netloc
        if parts.netloc and parts.path:
            path = parts.netloc + parts.path
        if not path:
            raise LinkError(f"{url!r}: serial link needs a device path")
        query = parse_qs(parts.query)
        try:
            baud = int(query.get("baud", [DEFAULT_BAUD])[0])
        except ValueError:
            raise LinkError(f"{url!r}: baud must be a number") from None
        return LinkSpec("serial", path=path, baud=baud)
    if parts.scheme == "tcp":
        if not parts.hostname or not parts.port:
            raise LinkError(f"{url!r}: tcp link needs host and port, e.g. tcp://127.0.0.1:9000")
        return LinkSpec("tcp", host=parts.hostname, port=parts.port)
    if parts.scheme in ("udp", "udpin", "udpout"):
        if not parts.port:
            raise LinkError(f"{url!r}: udp link needs a port, e.g. udp://127.0.0.1:14550")
        return LinkSpec("udp", host=parts.hostname or "0.0.0.0", port=parts.port)
    raise LinkError(
        f"{url!r}: unknown link; use serial:/dev/...?baud=N, /dev/..., tcp://h:p or udp://h:p"
    )


class SerialLink:
    def __init__(self, url: str, spec: LinkSpec) -> None:
        import serial  # pyserial; imported here so TCP-only users do not need it

        self.url = url
        self._serial_error = serial.SerialException
        try:
            self.port = serial.Serial(spec.path, spec.baud, timeout=0, exclusive=True)
        except (serial.SerialException, OSError, ValueError) as exc:
            raise LinkDown(f"{spec.path}: {exc}") from exc

    def read(self, max_bytes: int = 4096, timeout: float = 0.1) -> bytes:
        try:
            ready, _, _ = select.select([self.port.fileno()], [], [], timeout)
            if not ready:
                return b""
            data = self.port.read(max_bytes)
        except (self._serial_error, OSError, TypeError, ValueError) as exc:
            raise LinkDown(f"{self.url}: {exc}") from exc
        if not data:
            # Readable but empty: the other end of the pty/USB line is gone.
            raise LinkDown(f"{self.url}: line closed")
        return data

    def write(self, data: bytes) -> None:
        try:
            self.port.write(data)
        except (self._serial_error, OSError, TypeError, ValueError) as exc:
            raise LinkDown(f"{self.url}: {exc}") from exc

    def close(self) -> None:
        with contextlib.suppress(Exception):
            self.port.close()


class TcpLink:
    def __init__(self, url: str, spec: LinkSpec, connect_timeout: float = 3.0) -> None:
        self.url = url
        try:
            self.sock = socket.create_connection((spec.host, spec.port), timeout=connect_timeout)
        except OSError as exc:
            raise LinkDown(f"{url}: {exc}") from exc
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.sock.settimeout(None)
        self._wlock = threading.Lock()

    def read(self, max_bytes: int = 4096, timeout: float = 0.1) -> bytes:
        try:
            ready, _, _ = select.select([self.sock], [], [], timeout)
            if not ready:
                return b""
            data = self.sock.recv(max_bytes)
        except (OSError, ValueError) as exc:
            raise LinkDown(f"{self.url}: {exc}") from exc
        if not data:
            raise LinkDown(f"{self.url}: connection closed")
        return data

    def write(self, data: bytes) -> None:
        try:
            with self._wlock:
                self.sock.sendall(data)
        except (OSError, ValueError) as exc:
            raise LinkDown(f"{self.url}: {exc}") from exc

    def close(self) -> None:
        with contextlib.suppress(OSError):
            self.sock.close()


class UdpLink:
    """`udp://HOST:PORT` listens there and answers whoever sent last (a GCS on 14550);
    `udpout://HOST:PORT` (or `udp://HOST:PORT?connect`) sends to that address."""

    def __init__(self, url: str) -> None:
        parts = urlsplit(url)
        if not parts.port:
            raise LinkError(f"{url!r}: udp link needs a port, e.g. udp://127.0.0.1:14550")
        host = parts.hostname or "0.0.0.0"
        self.url = url
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.peer: tuple[str, int] | None = None
        self.unsent = 0
        connect = parts.scheme == "udpout" or "connect" in parse_qs(parts.query, True)
        try:
            if connect:
                self.peer = (host, parts.port)
                self.sock.bind(("0.0.0.0", 0))
            else:
                self.sock.bind((host, parts.port))
        except OSError as exc:
            self.sock.close()
            raise LinkDown(f"{url}: {exc}") from exc
        self.sock.setblocking(False)
        self.address = self.sock.getsockname()

    def read(self, max_bytes: int = 4096, timeout: float = 0.1) -> bytes:
        try:
            ready, _, _ = select.select([self.sock], [], [], timeout)
            if not ready:
                return b""
            data, addr = self.sock.recvfrom(65535)
        except (BlockingIOError, InterruptedError):
            return b""
        except OSError as exc:
            raise LinkDown(f"{self.url}: {exc}") from exc
        self.peer = addr
        return data

    def write(self, data: bytes) -> None:
        if self.peer is None:
            self.unsent += 1  # nobody has spoken yet: nowhere to answer
            return
        with contextlib.suppress(BlockingIOError):
            try:
                self.sock.sendto(data, self.peer)
            except OSError as exc:
                raise LinkDown(f"{self.url}: {exc}") from exc

    def close(self) -> None:
        with contextlib.suppress(OSError):
            self.sock.close()


def open_link(url: str) -> Link:
    """Open the link a URL names; raise LinkError for a bad URL, LinkDown when it is absent."""
    spec = parse_link_url(url)
    if spec.kind == "tcp":
        return TcpLink(url, spec)
    if spec.kind == "udp":
        return UdpLink(url)
    return SerialLink(url, spec)


class ReopeningLink:
    """A link that reopens its URL after the line vanishes.

    `read`/`write` raise LinkDown while the line is away; the next call tries to reopen
    (at most every `retry_s`). `generation` counts successful opens, so a user can tell
    that it is talking to a fresh line (and restart its handshake).
    """

    def __init__(self, url: str, *, retry_s: float = 0.5) -> None:
        parse_link_url(url)  # fail fast on a malformed URL
        self.url = url
        self.retry_s = retry_s
        self.generation = 0
        self.drops = 0
        self._link: Link | None = None
        self._lock = threading.Lock()
        self._next_try = 0.0
        self._closed = False

    @property
    def is_open(self) -> bool:
        return self._link is not None

    def _ensure(self) -> Link:
        with self._lock:
            if self._closed:
                raise LinkDown(f"{self.url}: closed")
            if self._link is not None:
                return self._link
            now = time.monotonic()
            if now < self._next_try:
                raise LinkDown(f"{self.url}: waiting to reopen")
            self._next_try = now + self.retry_s
            self._link = open_link(self.url)
            self.generation += 1
            log.info("link %s open (generation %d)", self.url, self.generation)
            return self._link

    def _drop(self, link: Link) -> None:
        with self._lock:
            if self._link is link:
                self._link = None
                self.drops += 1
                self._next_try = time.monotonic() + self.retry_s
        link.close()

    def read(self, max_bytes: int = 4096, timeout: float = 0.1) -> bytes:
        try:
            link = self._ensure()
        except LinkDown:
            time.sleep(min(timeout, self.retry_s))
            raise
        try:
            return link.read(max_bytes, timeout)
        except LinkDown:
            self._drop(link)
            raise

    def write(self, data: bytes) -> None:
        link = self._ensure()
        try:
            link.write(data)
        except LinkDown:
            self._drop(link)
            raise

    def reopen(self) -> None:
        """Drop the line now; the next read or write opens it again."""
        with self._lock:
            link, self._link = self._link, None
            self._next_try = 0.0
        if link is not None:
            link.close()

    def close(self) -> None:
        with self._lock:
            self._closed = True
            link, self._link = self._link, None
        if link is not None:
            link.close()
