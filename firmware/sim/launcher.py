"""Start simulators as subprocesses from Python (tests, the fleet launcher)."""

from __future__ import annotations

import contextlib
import os
import select
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

REPO_ROOT = Path(__file__).resolve().parents[2]


class SimulatorError(RuntimeError):
    """The simulator did not start, or did not say where it listens."""


@dataclass
class SimulatorProcess:
    process: subprocess.Popen
    pty_path: str | None = None
    tcp_address: tuple[str, int] | None = None
    args: list[str] = field(default_factory=list)

    @property
    def pid(self) -> int:
        return self.process.pid

    @property
    def url(self) -> str:
        """Link URL for the flight-controller driver."""
        if self.tcp_address is not None:
            return f"tcp://{self.tcp_address[0]}:{self.tcp_address[1]}"
        return f"serial:{self.pty_path}"

    def alive(self) -> bool:
        return self.process.poll() is None

    def stop(self, timeout: float = 5.0) -> None:
        """SIGTERM, then SIGKILL if it does not exit within timeout."""
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGTERM)
            try:
                self.process.wait(timeout)
            except subprocess.TimeoutExpired:
                self.kill()
        self._close_pipes()

    def kill(self) -> None:
        if self.process.poll() is None:
            self.process.kill()
            self.process.wait(5)
        self._close_pipes()

    def _close_pipes(self) -> None:
        for pipe in (self.process.stdout, self.process.stderr):
            if pipe is not None and not pipe.closed:
                pipe.close()

    def __enter__(self) -> SimulatorProcess:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


def start_simulator(
    home: tuple[float, float, float] = (38.736946, -9.142685, 100.0),
    time_scale: float = 1.0,
    arming_line: str | os.PathLike[str] | None = None,
    *,
    tcp_port: int | None = None,
    pty_link: str | os.PathLike[str] | None = None,
    battery_capacity_mah: float | None = None,
    drain: float | None = None,
    max_horizontal_speed: float | None = None,
    arming_time: float | None = None,
    firmware: str | None = None,
    log_file: str | os.PathLike[str] | None = None,
    extra_args: list[str] | None = None,
    # Seconds for it to start; starting takes about a second of CPU, many on a busy machine.
    startup_timeout: float = 60.0,
) -> SimulatorProcess:
    """Run `python -m firmware.sim` and return once it has printed where it listens."""
    args = [
        sys.executable,
        "-m",
        "firmware.sim",
        "--home",
        ",".join(str(v) for v in home),
        "--time-scale",
        str(time_scale),
    ]
    optional = {
        "--arming-line": arming_line,
        "--tcp": tcp_port,
        "--pty-link": pty_link,
        "--battery-capacity-mah": battery_capacity_mah,
        "--drain": drain,
        "--max-horizontal-speed": max_horizontal_speed,
        "--arming-time": arming_time,
        "--firmware": firmware,
    }
    for flag, value in optional.items():
        if value is not None:
            args += [flag, str(value)]
    args += extra_args or []
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(REPO_ROOT), env.get("PYTHONPATH")]))
    with contextlib.ExitStack() as stack:
        stderr: Any = subprocess.DEVNULL
        if log_file is not None:
            stderr = stack.enter_context(open(log_file, "ab"))  # the child keeps its own copy
        process = subprocess.Popen(
            args, stdout=subprocess.PIPE, stderr=stderr, cwd=REPO_ROOT, env=env
        )
    sim = SimulatorProcess(process, args=args)
    _take_announcement(sim, _read_line(process, startup_timeout), startup_timeout)
    return sim


def _take_announcement(sim: SimulatorProcess, line: str, waited_s: float) -> None:
    """Where the simulator listens, from the first line it printed; SimulatorError (and
    the process killed) when it printed none."""
    if line.startswith("pty: "):
        sim.pty_path = line[5:]
    elif line.startswith("tcp: "):
        host, _, port = line[5:].rpartition(":")
        sim.tcp_address = (host, int(port))
    else:
        try:  # a closed output is most often a process on its way out
            code: int | None = sim.process.wait(timeout=1.0)
        except subprocess.TimeoutExpired:
            code = None
        sim.kill()
        why = f"exited with {code}" if code is not None else f"nothing in {waited_s:g} s"
        raise SimulatorError(f"simulator did not announce its link ({why}; got {line!r})")


def _read_line(process: subprocess.Popen, timeout: float) -> str:
    assert process.stdout is not None
    deadline = time.monotonic() + timeout
    buf = b""
    fd = process.stdout.fileno()
    while b"\n" not in buf:
        left = deadline - time.monotonic()
        if left <= 0 or process.poll() is not None:
            break
        ready, _, _ = select.select([fd], [], [], left)
        if ready:
            chunk = os.read(fd, 256)
            if not chunk:
                break
            buf += chunk
    return buf.split(b"\n", 1)[0].decode(errors="replace").strip()
