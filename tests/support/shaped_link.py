"""A drone's radio link as a test shapes it: one bottleneck from the drone to the ground
that both its MQTT connection (TCP) and its live video (WebRTC over UDP) cross.

- `Uplink`: a first-in first-out queue drained at `rate_bps` after `latency_s`, as a radio
  modem's buffer is. When more than `max_queue_s` of traffic waits, a datagram is dropped
  (counted); a TCP chunk is always queued, as the sender's TCP would resend it anyway.
  Every byte offered to it is recorded with its time, so a test measures what the drone
  sent as well as what the link carried.
- `TcpRelay`: connections to its port are relayed to a target, the drone's direction
  through the uplink, the ground's direction at once.
- `MediaRelay` and `WhipProxy`: WHIP through a proxy that rewrites the offer's and the
  answer's ICE candidates ([RFC 8445] host candidates) to the relay's two UDP sockets, so
  every packet of the session, the ICE checks included, crosses the relay: the drone's
  through the uplink, the ground's (RTCP feedback) at once.
"""

from __future__ import annotations

import collections
import http.server
import re
import socket
import threading
import time
import urllib.error
import urllib.request
from collections.abc import Callable

CANDIDATE = re.compile(
    r"^a=candidate:(?P<foundation>\S+) (?P<component>\d+) (?P<transport>udp) (?P<priority>\d+) "
    r"(?P<ip>\d+\.\d+\.\d+\.\d+) (?P<port>\d+) typ host.*$",
    re.IGNORECASE | re.MULTILINE,
)


class Uplink:
    def __init__(self, latency_s: float = 0.01, max_queue_s: float = 1.0) -> None:
        self.latency_s = latency_s
        self.max_queue_s = max_queue_s
        self.rate_bps: float | None = None
        # (time, bytes, what) of everything sent into it, "what" naming the traffic.
        self.offered: list[tuple[float, int, str]] = []
        self.dropped = 0
        self._free_at = 0.0  # when the link has sent everything queued so far
        self._queue: collections.deque[tuple[float, Callable[[], None]]] = collections.deque()
        self._cond = threading.Condition()
        self._closed = False
        threading.Thread(target=self._deliver, name="uplink", daemon=True).start()

    def set_rate(self, rate_bps: float | None) -> None:
        with self._cond:
            self.rate_bps = rate_bps

    def send(self, size: int, deliver: Callable[[], None], *, droppable: bool, what: str) -> bool:
        """Queue `size` bytes whose `deliver` runs when the link has carried them; False
        when the datagram was dropped (the queue held more than max_queue_s)."""
        with self._cond:
            now = time.monotonic()
            self.offered.append((now, size, what))
            start = max(now, self._free_at)
            if droppable and self.rate_bps is not None and start - now > self.max_queue_s:
                self.dropped += 1
                return False
            serialise = size * 8 / self.rate_bps if self.rate_bps else 0.0
            self._free_at = start + serialise
            self._queue.append((self._free_at + self.latency_s, deliver))
            self._cond.notify()
            return True

    def offered_bps(self, what: str, since: float, until: float) -> float:
        """The bitrate of `what` offered to the link from `since` to `until` (monotonic)."""
        with self._cond:
            total = sum(s for at, s, w in self.offered if w == what and since <= at < until)
        return total * 8 / (until - since)

    def close(self) -> None:
        with self._cond:
            self._closed = True
            self._cond.notify()

    def _deliver(self) -> None:
        while True:
            with self._cond:
                while not self._closed and (
                    not self._queue or self._queue[0][0] > time.monotonic()
                ):
                    wait = self._queue[0][0] - time.monotonic() if self._queue else None
                    self._cond.wait(wait)
                if self._closed:
                    return
                _, deliver = self._queue.popleft()
            try:
                deliver()
            except OSError:
                pass


class TcpRelay:
    """Connections to `port` relayed to `target`: the client's bytes through `uplink`."""

    def __init__(self, target: tuple[str, int], uplink: Uplink) -> None:
        self.target = target
        self.uplink = uplink
        self.listener = socket.create_server(("127.0.0.1", 0))
        self.port = self.listener.getsockname()[1]
        self._sockets: list[socket.socket] = []
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self) -> None:
        while True:
            try:
                client, _ = self.listener.accept()
            except OSError:
                return
            server = socket.create_connection(self.target)
            self._sockets += [client, server]
            threading.Thread(target=self._up, args=(client, server), daemon=True).start()
            threading.Thread(target=self._down, args=(server, client), daemon=True).start()

    def _up(self, client: socket.socket, server: socket.socket) -> None:
        try:
            while data := client.recv(4096):
                self.uplink.send(
                    len(data), lambda d=data: server.sendall(d), droppable=False, what="tcp"
                )
        except OSError:
            pass

    def _down(self, server: socket.socket, client: socket.socket) -> None:
        try:
            while data := server.recv(65536):
                client.sendall(data)
        except OSError:
            pass

    def close(self) -> None:
        self.listener.close()
        for sock in self._sockets:
            sock.close()


class MediaRelay:
    """Two UDP sockets between a drone and the media server: `drone_side` is the address
    the drone is told the server has, `ground_side` the one the server is told the drone
    has."""

    def __init__(self, uplink: Uplink) -> None:
        self.uplink = uplink
        self.drone_side = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.ground_side = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        for sock in (self.drone_side, self.ground_side):
            sock.bind(("0.0.0.0", 0))
        self.drone: tuple[str, int] | None = None  # the drone's own candidate
        self.server: tuple[str, int] | None = None  # the media server's own candidate
        threading.Thread(target=self._from_drone, daemon=True).start()
        threading.Thread(target=self._from_server, daemon=True).start()

    def _from_drone(self) -> None:
        while True:
            try:
                data, source = self.drone_side.recvfrom(65536)
            except OSError:
                return
            self.drone = source
            if self.server is not None:
                server = self.server
                self.uplink.send(
                    len(data),
                    lambda d=data, s=server: self.ground_side.sendto(d, s),
                    droppable=True,
                    what="media",
                )

    def _from_server(self) -> None:
        while True:
            try:
                data, _ = self.ground_side.recvfrom(65536)
            except OSError:
                return
            if self.drone is not None:
                try:
                    self.drone_side.sendto(data, self.drone)
                except OSError:  # closed meanwhile: the relay ends with the link
                    return

    def close(self) -> None:
        for sock in (self.drone_side, self.ground_side):
            sock.close()


def through(sdp: str, port: int) -> tuple[str, tuple[str, int]]:
    """`sdp` with its candidates replaced by one at the same host's `port`, and the
    address of the IPv4 UDP host candidate it named."""
    match = CANDIDATE.search(sdp)
    if match is None:
        raise ValueError("the description names no IPv4 UDP host candidate")
    address = (match["ip"], int(match["port"]))
    line = (f"a=candidate:{match['foundation']} {match['component']} udp {match['priority']} "
            f"{match['ip']} {port} typ host")  # fmt: skip
    kept: list[str] = []
    for original in sdp.split("\r\n"):
        if not original.startswith("a=candidate:"):
            kept.append(original)
        elif line not in kept:
            kept.append(line)
    return "\r\n".join(kept), address


class WhipProxy:
    """WHIP to `target` (the media server's drones' side) through `relay`."""

    def __init__(self, target: str, relay: MediaRelay) -> None:
        proxy = self

        class Handler(http.server.BaseHTTPRequestHandler):
            def do_POST(self) -> None:  # noqa: N802 - http.server's name
                length = int(self.headers.get("Content-Length") or 0)
                offer = self.rfile.read(length).decode()
                offer, relay.drone = through(offer, relay.ground_side.getsockname()[1])
                status, body, headers = proxy.forward(self, "POST", offer.encode())
                if status == 201:
                    answer, relay.server = through(body.decode(), relay.drone_side.getsockname()[1])
                    body = answer.encode()
                self.answer(status, body, headers)

            def do_DELETE(self) -> None:  # noqa: N802 - http.server's name
                self.answer(*proxy.forward(self, "DELETE", None))

            def answer(self, status: int, body: bytes, headers: dict[str, str]) -> None:
                self.send_response(status)
                for name in ("Content-Type", "Location"):
                    if headers.get(name):
                        self.send_header(name, headers[name])
                self.send_header("Content-Length", str(len(body)))
                self.end_headers()
                self.wfile.write(body)

            def log_message(self, *args: object) -> None:
                pass

        self.target = target.rstrip("/")
        self.server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.url = f"http://127.0.0.1:{self.server.server_address[1]}"
        threading.Thread(target=self.server.serve_forever, daemon=True).start()

    def forward(
        self, handler: http.server.BaseHTTPRequestHandler, method: str, body: bytes | None
    ) -> tuple[int, bytes, dict[str, str]]:
        headers = {
            k: v for k, v in handler.headers.items() if k in ("Authorization", "Content-Type")
        }
        request = urllib.request.Request(
            self.target + handler.path, data=body, method=method, headers=headers
        )
        try:
            with urllib.request.urlopen(request, timeout=15) as response:
                return response.status, response.read(), dict(response.headers)
        except urllib.error.HTTPError as exc:
            return exc.code, exc.read(), dict(exc.headers)

    def close(self) -> None:
        self.server.shutdown()
        self.server.server_close()
