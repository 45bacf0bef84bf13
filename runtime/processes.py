"""Waiting, free ports and supervised subprocesses, for whatever starts real processes.

The simulated-fleet launcher (firmware.sim.fleet), the replicated ground (workers.ground),
the benchmarks, `make run`, `make loadtest` and the tests all start processes and wait on
them the same way; this module is the one place that does it. It lives in the lowest
layer (standard library only) so every other layer may import it.
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import threading
import time
from collections import deque
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

REPO_ROOT = Path(__file__).resolve().parent.parent
# How many of a supervised process's last output lines `output()` keeps.
ECHO_LINES = 10_000


def wait_for(predicate: Callable[[], Any], timeout: float = 10.0, interval: float = 0.05) -> Any:
    """The first truthy value of `predicate()` within `timeout` s, else its last value."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(interval)
    return predicate()


def free_port() -> int:
    """A TCP port nothing listens on now (the OS's choice) on 127.0.0.1."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def port_open(port: int, host: str = "127.0.0.1", timeout: float = 0.2) -> bool:
    """Whether something accepts TCP connections on host:port."""
    try:
        with socket.create_connection((host, port), timeout=timeout):
            return True
    except OSError:
        return False


def stop_process(process: subprocess.Popen, timeout: float = 10.0) -> int | None:
    """Ask the process to end (SIGTERM), kill it if it has not within `timeout` s; its code."""
    if process.poll() is None:
        process.terminate()
        try:
            process.wait(timeout)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
    return process.returncode


def python_env(base: Mapping[str, str] | None = None, **extra: str) -> dict[str, str]:
    """The environment for a `python -m ...` child of this checkout: the repository on
    PYTHONPATH ahead of what was there."""
    env = dict(os.environ if base is None else base)
    paths = [str(REPO_ROOT), env.get("PYTHONPATH", "")]
    env["PYTHONPATH"] = os.pathsep.join(p for p in paths if p)
    env.update(extra)
    return env


@dataclass
class Supervised:
    """One subprocess: its command, its log file, how to tell that it is ready.

    It runs in a process group of its own, so `kill()` ends it and its children (a worker
    pool, an ingest's children) the way a crash would, and a terminal's Ctrl-C reaches
    only whoever supervises it; with `own_group=False` it stays in its supervisor's group
    instead, so that whatever ends the supervisor's group ends it too. Its output (stdout and stderr) is appended to `log_path`,
    and with `echo` (a prefix) also written line by line to this process's stdout, and
    with `on_line` also given to it line by line; `on_exit(code)` is called when a process
    read that way ends. Readiness is judged on what the current start wrote: every line of
    `ready_text` seen and, when `port` is set, the port accepting connections.
    """

    name: str
    argv: Sequence[str]
    env: Mapping[str, str] | None = None
    log_path: Path | None = None
    ready_text: tuple[str, ...] = ()
    port: int | None = None
    cwd: Path = REPO_ROOT
    own_group: bool = True
    echo: str | None = None
    on_line: Callable[[str], None] | None = None
    on_exit: Callable[[int], None] | None = None
    process: subprocess.Popen | None = None
    starts: int = 0
    _log_offset: int = field(default=0, repr=False)
    # The last lines only: a process that runs for days must not grow its supervisor.
    _echoed: deque[str] = field(default_factory=lambda: deque(maxlen=ECHO_LINES), repr=False)
    _pump_thread: threading.Thread | None = field(default=None, repr=False)

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.port}"

    @property
    def alive(self) -> bool:
        return self.process is not None and self.process.poll() is None

    @property
    def pid(self) -> int | None:
        return self.process.pid if self.process is not None else None

    def start(self) -> Supervised:
        if self.alive:
            raise RuntimeError(f"{self.name} is already running")
        log = self._open_log()
        try:
            self.process = subprocess.Popen(
                list(self.argv),
                cwd=self.cwd,
                env=dict(self.env) if self.env is not None else None,
                stdout=subprocess.PIPE if self._read_lines else log,
                stderr=subprocess.STDOUT,
                stdin=subprocess.DEVNULL,
                start_new_session=self.own_group,
            )
        finally:
            if log is not subprocess.DEVNULL:
                log.close()  # type: ignore[union-attr]
        self.starts += 1
        if self._read_lines:
            self._echoed = deque(maxlen=ECHO_LINES)
            self._pump_thread = threading.Thread(target=self._pump, args=(self.process,))
            self._pump_thread.daemon = True
            self._pump_thread.start()
        return self

    @property
    def _read_lines(self) -> bool:
        return self.echo is not None or self.on_line is not None

    def _pump(self, process: subprocess.Popen) -> None:
        """Keep each line for readiness, append it to the log, echo it, hand it on."""
        assert process.stdout is not None
        log = open(self.log_path, "ab") if self.log_path else None  # noqa: SIM115
        try:
            for raw in process.stdout:
                line = raw.decode(errors="replace")
                self._echoed.append(line)
                if self.echo is not None:
                    sys.stdout.write(f"{self.echo}{line}")
                    sys.stdout.flush()
                if self.on_line is not None:
                    self.on_line(line)
                if log is not None:
                    log.write(raw)
                    log.flush()
        finally:
            if log is not None:
                log.close()
        code = process.wait()
        if self.on_exit is not None:
            self.on_exit(code)

    def _open_log(self) -> Any:
        if self.log_path is None:
            return subprocess.DEVNULL
        self.log_path.parent.mkdir(parents=True, exist_ok=True)
        # Readiness is judged on what this start writes, not on an earlier run's lines.
        self._log_offset = self.log_path.stat().st_size if self.log_path.exists() else 0
        return open(self.log_path, "ab")  # noqa: SIM115 - closed once the child has it

    def output(self) -> str:
        """What this process wrote since its last start."""
        if self._read_lines:
            return "".join(self._echoed)
        if self.log_path is None or not self.log_path.exists():
            return ""
        with open(self.log_path, "rb") as log:
            log.seek(self._log_offset)
            return log.read().decode(errors="replace")

    def is_ready(self) -> bool:
        if not self.alive:
            return False
        if self.port is not None and not port_open(self.port):
            return False
        output = self.output() if self.ready_text else ""
        return all(text in output for text in self.ready_text)

    def wait_ready(self, timeout: float = 60.0) -> Supervised:
        """Return once ready; raise with the log's tail if it exits or takes too long."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.is_ready():
                return self
            if self.process is not None and self.process.poll() is not None:
                raise RuntimeError(f"{self.name} exited early:\n{self.output()[-3000:]}")
            time.sleep(0.1)
        raise RuntimeError(f"{self.name} not ready in {timeout:.0f} s:\n{self.output()[-3000:]}")

    def send(self, sig: int) -> None:
        """Send `sig` to the process and, when it has its own group, to the whole group."""
        if self.process is None:
            return
        try:
            if self.own_group:
                os.killpg(self.process.pid, sig)
            elif self.process.poll() is None:
                self.process.send_signal(sig)
        except ProcessLookupError:
            pass

    def kill(self, sig: int = signal.SIGKILL) -> None:
        """End it (its whole group) with `sig` (SIGKILL: a crash, nothing drained)."""
        self.send(sig)
        if sig == signal.SIGKILL and self.process is not None:
            self.process.wait(10)

    def stop(self, timeout: float = 15.0) -> int | None:
        """SIGTERM to the leader (it drains on it), then nothing of its group outlives it;
        the leader's exit code."""
        if self.process is None:
            return None
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(timeout)
            except subprocess.TimeoutExpired:
                pass
        self.kill(signal.SIGKILL)
        if self._pump_thread is not None:
            self._pump_thread.join(5)  # the last lines are read before we return
        return self.process.returncode

    def restart(self, timeout: float = 60.0) -> None:
        if self.alive:
            self.stop()
        self.start().wait_ready(timeout)
