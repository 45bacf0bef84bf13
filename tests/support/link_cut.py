"""A TCP relay whose link can be cut: a drone's uplink that drops mid-transfer.

Connections to `port` are relayed to the target. `cut_after(n)` closes every relayed
connection once n more bytes went client → server and refuses new ones (they are closed
at once) until `restore()`.
"""

from __future__ import annotations

import socket
import threading


class LinkCut:
    def __init__(self, target_host: str, target_port: int) -> None:
        self.target = (target_host, target_port)
        self.listener = socket.create_server(("127.0.0.1", 0))
        self.port = self.listener.getsockname()[1]
        self.forwarded = 0
        self.down = False
        self.cuts = 0
        self._budget: int | None = None
        self._sockets: list[socket.socket] = []
        self._lock = threading.Lock()
        threading.Thread(target=self._accept, daemon=True).start()

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.port}"

    def cut_after(self, n: int) -> None:
        with self._lock:
            self._budget = n

    def restore(self) -> None:
        with self._lock:
            self.down, self._budget = False, None

    def _cut(self) -> None:
        self.down, self._budget = True, None
        self.cuts += 1
        for sock in self._sockets:
            try:
                sock.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
            sock.close()
        self._sockets.clear()

    def _accept(self) -> None:
        while True:
            try:
                client, _ = self.listener.accept()
            except OSError:
                return
            with self._lock:
                if self.down:
                    client.close()
                    continue
                server = socket.create_connection(self.target)
                self._sockets += [client, server]
            threading.Thread(target=self._pipe, args=(client, server, True), daemon=True).start()
            threading.Thread(target=self._pipe, args=(server, client, False), daemon=True).start()

    def _pipe(self, source: socket.socket, sink: socket.socket, upward: bool) -> None:
        try:
            while data := source.recv(16384):
                with self._lock:
                    if upward and self._budget is not None:
                        if len(data) > self._budget:
                            self._cut()
                            return
                        self._budget -= len(data)
                    if upward:
                        self.forwarded += len(data)
                sink.sendall(data)
        except OSError:
            pass
        finally:
            for sock in (source, sink):
                try:
                    sock.close()
                except OSError:
                    pass

    def close(self) -> None:
        self.listener.close()
        with self._lock:
            self._cut()
