"""Thin I/O around BoardSession: a raw pseudo-terminal, or a TCP port like dRonin's flightd."""

from __future__ import annotations

import contextlib
import errno
import logging
import os
import select
import socket
import termios
import time
import tty
from pathlib import Path

from firmware.sim.telemetry import BoardSession

log = logging.getLogger(__name__)

TICK_S = 0.005  # wall-clock seconds between physics/telemetry ticks at most
MAX_BACKLOG = 64 * 1024  # bytes queued for a reader that does not read: older ones dropped


class PtyTransport:
    """The master side of a pty; the slave path is what a ground station opens."""

    def __init__(self, link: Path | None = None) -> None:
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        tty.setraw(self.master)
        os.set_blocking(self.master, False)
        self.path = os.ttyname(self.slave)
        self.link = link
        if link is not None:
            # A stable name that survives a simulator restart (the pty number does not).
            tmp = link.with_name(f".{link.name}.{os.getpid()}")
            with contextlib.suppress(FileNotFoundError):
                tmp.unlink()
            tmp.symlink_to(self.path)
            tmp.replace(link)
        self.backlog = bytearray()
        self.dropped = 0

    def announce(self) -> str:
        return f"pty: {self.path}"

    def fds(self) -> list[int]:
        return [self.master]

    def read(self, ready: list[int]) -> bytes:
        if self.master not in ready:
            return b""
        try:
            return os.read(self.master, 4096)
        except BlockingIOError:
            return b""
        except OSError as exc:  # EIO while no one has the slave open on some kernels
            if exc.errno != errno.EIO:
                raise
            return b""

    def write(self, data: bytes) -> None:
        self.backlog += data
        if len(self.backlog) > MAX_BACKLOG:
            # Nobody reads the line: behave like a UART and lose the oldest bytes.
            cut = len(self.backlog) - MAX_BACKLOG
            self.dropped += cut
            del self.backlog[:cut]
        while self.backlog:
            try:
                sent = os.write(self.master, self.backlog)
            except (BlockingIOError, InterruptedError):
                return
            except OSError as exc:
                if exc.errno in (errno.EIO, errno.EAGAIN):
                    return
                raise
            del self.backlog[:sent]

    def drop_link(self) -> None:
        self.backlog.clear()
        with contextlib.suppress(termios.error, OSError):
            termios.tcflush(self.master, termios.TCIOFLUSH)

    def close(self) -> None:
        for fd in (self.master, self.slave):
            with contextlib.suppress(OSError):
                os.close(fd)
        if self.link is not None and self.link.is_symlink():
            with contextlib.suppress(OSError):
                if os.readlink(self.link) == self.path:
                    self.link.unlink()


class TcpTransport:
    """One ground station at a time on a TCP port; a new connection replaces the old one."""

    def __init__(self, host: str, port: int) -> None:
        self.listener = socket.create_server((host, port))
        self.listener.setblocking(False)
        self.host, self.port = self.listener.getsockname()[:2]
        self.client: socket.socket | None = None
        self.backlog = bytearray()
        self.on_connect = None

    def announce(self) -> str:
        return f"tcp: {self.host}:{self.port}"

    def fds(self) -> list[int]:
        fds = [self.listener.fileno()]
        if self.client is not None:
            fds.append(self.client.fileno())
        return fds

    def read(self, ready: list[int]) -> bytes:
        if self.listener.fileno() in ready:
            with contextlib.suppress(BlockingIOError):
                client, addr = self.listener.accept()
                log.info("ground station connected from %s", addr)
                self.drop_link()
                client.setblocking(False)
                client.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                self.client = client
        if self.client is None or self.client.fileno() not in ready:
            return b""
        try:
            data = self.client.recv(4096)
        except BlockingIOError:
            return b""
        except OSError:
            data = b""
        if not data:
            self.drop_link()
        return data

    def write(self, data: bytes) -> None:
        if self.client is None:
            return
        self.backlog += data
        try:
            sent = self.client.send(self.backlog)
            del self.backlog[:sent]
        except BlockingIOError:
            if len(self.backlog) > MAX_BACKLOG:
                del self.backlog[: len(self.backlog) - MAX_BACKLOG]
        except OSError:
            self.drop_link()

    def drop_link(self) -> None:
        if self.client is not None:
            with contextlib.suppress(OSError):
                self.client.close()
        self.client = None
        self.backlog.clear()

    def close(self) -> None:
        self.drop_link()
        self.listener.close()


def serve(session: BoardSession, transport: PtyTransport | TcpTransport, stop) -> None:
    """Run until stop() is true: read, tick, write; never dies on what the ground sends."""
    session.on_reboot = transport.drop_link
    while not stop():
        ready, _, _ = select.select(transport.fds(), [], [], TICK_S)
        now = time.monotonic()
        data = transport.read(ready)
        if data:
            session.receive(data, now)
        session.tick(now)
        out = session.take_output()
        if out:
            transport.write(out)
        elif getattr(transport, "backlog", None):
            transport.write(b"")
