"""A drone's radio link made of the kernel's own parts: a network namespace whose only way
out is a veth pair to the host, the namespace side's egress shaped by `tc` (an HTB class
at the link's rate over a first-in first-out buffer, or fq_codel). A process run in the
namespace (`NetnsLink.wrap`) reaches the host only through it, and its TCP connections'
acknowledgements come back through it, as they would over a radio: the kernel of the
drone's computer sees the link's queue in its own connections.

Services on the host listen on 127.0.0.1; `Forwarder` relays a port of the host side's
address to one of them. The namespace's default route is the host side, so the host's
other addresses (the media server's ICE candidates) are reached through the link too.

Needs CAP_NET_ADMIN (`available` says why not).
"""

from __future__ import annotations

import os
import socket
import subprocess
import threading
import uuid

OPEN_BPS = 1_000_000_000


def _run(*argv: str) -> str:
    result = subprocess.run(argv, capture_output=True, text=True, timeout=20)
    if result.returncode != 0:
        raise OSError(f"{' '.join(argv)}: {result.stderr.strip()}")
    return result.stdout


def available() -> str | None:
    """None when namespaces and tc can be used here, else why not."""
    name = f"shk{uuid.uuid4().hex[:8]}"
    try:
        _run("ip", "netns", "add", name)
    except (OSError, FileNotFoundError, subprocess.TimeoutExpired) as exc:
        return f"no network namespaces here ({exc})"
    _run("ip", "netns", "del", name)
    try:
        _run("tc", "-V")
    except (OSError, FileNotFoundError) as exc:
        return f"no tc here ({exc})"
    return None


class NetnsLink:
    """A namespace, its veth pair and its shaped egress; `close` removes them all."""

    def __init__(self) -> None:
        tag = uuid.uuid4().hex[:8]
        self.netns, self.host_dev, self.drone_dev = f"shn{tag}", f"shh{tag}", f"shd{tag}"
        # A /30 of 10.213.0.0/16 per process: tests in parallel take different ones.
        index = (os.getpid() * 7 + int(tag[:4], 16)) % 16384
        base = f"10.213.{index // 64}.{(index % 64) * 4}"
        prefix = base.rsplit(".", 1)[0]
        last = int(base.rsplit(".", 1)[1])
        self.host_address, self.drone_address = f"{prefix}.{last + 1}", f"{prefix}.{last + 2}"
        try:
            self._create()
        except BaseException:
            self.close()
            raise

    def _create(self) -> None:
        ns, host, drone = self.netns, self.host_dev, self.drone_dev
        _run("ip", "netns", "add", ns)
        _run("ip", "link", "add", host, "type", "veth", "peer", "name", drone, "netns", ns)
        _run("ip", "addr", "add", f"{self.host_address}/30", "dev", host)
        _run("ip", "link", "set", host, "up")
        _run("ip", "-n", ns, "addr", "add", f"{self.drone_address}/30", "dev", drone)
        _run("ip", "-n", ns, "link", "set", "lo", "up")
        _run("ip", "-n", ns, "link", "set", drone, "up")
        _run("ip", "-n", ns, "route", "add", "default", "via", self.host_address)
        _run("tc", "-n", ns, "qdisc", "add", "dev", drone, "root", "handle", "1:", "htb",
             "default", "1")  # fmt: skip
        _run("tc", "-n", ns, "class", "add", "dev", drone, "parent", "1:", "classid", "1:1",
             "htb", "rate", f"{OPEN_BPS}bit", "quantum", "1514")  # fmt: skip

    def wrap(self, argv: list[str]) -> list[str]:
        """`argv` run inside the namespace."""
        return ["ip", "netns", "exec", self.netns, *argv]

    def shape(self, rate_bps: int, buffer_s: float, *, queue: str = "bfifo") -> None:
        """The drone's egress at `rate_bps` over a `queue` ("bfifo": first in first out,
        dropping beyond `buffer_s` of the rate; "fq_codel": Linux's default, its flows
        isolated, limited to the same bytes)."""
        ns, drone = self.netns, self.drone_dev
        limit = max(3000, int(rate_bps * buffer_s / 8))
        leaf = (["bfifo", "limit", str(limit)] if queue == "bfifo"
                else ["fq_codel", "memory_limit", str(max(limit, 32768))])  # fmt: skip
        handle = "10:" if queue == "bfifo" else "20:"  # a kind of its own, a handle of its own
        _run("tc", "-n", ns, "qdisc", "replace", "dev", drone, "parent", "1:1", "handle",
             handle, *leaf)  # fmt: skip
        _run("tc", "-n", ns, "class", "change", "dev", drone, "parent", "1:", "classid",
             "1:1", "htb", "rate", f"{rate_bps}bit", "ceil", f"{rate_bps}bit",
             "burst", "1600", "cburst", "1600", "quantum", "1514")  # fmt: skip

    def stats(self) -> str:
        return _run("tc", "-s", "-n", self.netns, "qdisc", "show", "dev", self.drone_dev)

    def close(self) -> None:
        # Deleting the namespace deletes its end of the pair, and so the pair.
        for argv in (("ip", "netns", "del", self.netns), ("ip", "link", "del", self.host_dev)):
            subprocess.run(argv, capture_output=True, timeout=20)


class Forwarder:
    """Connections to `listen_host`:`port` relayed to 127.0.0.1:`target_port`."""

    def __init__(self, listen_host: str, target_port: int) -> None:
        self.target_port = target_port
        self.listener = socket.create_server((listen_host, 0))
        self.port = self.listener.getsockname()[1]
        self._sockets: list[socket.socket] = []
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self) -> None:
        while True:
            try:
                client, _ = self.listener.accept()
                server = socket.create_connection(("127.0.0.1", self.target_port))
            except OSError:
                return
            self._sockets += [client, server]
            for a, b in ((client, server), (server, client)):
                threading.Thread(target=self._pipe, args=(a, b), daemon=True).start()

    @staticmethod
    def _pipe(source: socket.socket, sink: socket.socket) -> None:
        try:
            while data := source.recv(65536):
                sink.sendall(data)
        except OSError:
            pass
        finally:
            for sock in (source, sink):
                try:
                    sock.shutdown(socket.SHUT_RDWR)
                except OSError:
                    pass

    def close(self) -> None:
        self.listener.close()
        for sock in self._sockets:
            sock.close()
