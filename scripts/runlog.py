"""What `make run` shows of its processes: one line per process when it starts, then only
warnings, errors (with their tracebacks) and the drones' important events (lines tagged
`[event]`, missions/eventlog.py). Every line, shown or not, goes to the process's own log
file under .data/run/logs/, so Celery beat's "Sending due task", uvicorn's access log and
the like are there when needed and out of the way otherwise."""

from __future__ import annotations

import re
import sys
from collections import deque
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
LOG_DIR = ROOT / ".data" / "run" / "logs"
EVENT_TAG = "[event]"  # missions/eventlog.py's EVENT_TAG (scripts import no app)

# A line at warning level or above in the formats our processes write: Django's LOGGING
# ("… WARNING name: …"), Celery ("[…: ERROR/MainProcess] …"), uvicorn ("ERROR:    …").
SEVERE = re.compile(r"(^|[\s:\[])(WARNING|ERROR|CRITICAL|FATAL)([\s:/\]]|$)")
TRACEBACK = "Traceback (most recent call last)"
# A line that starts a new log record; lines after a shown error up to the next such
# line belong to it (a traceback, a multi-line message).
RECORD_START = re.compile(r"^(\[?\d{4}-\d\d-\d\d[ T]|(DEBUG|INFO|WARNING|ERROR|CRITICAL):)")


class OutputFilter:
    """Decides line by line what of one process's output is shown."""

    def __init__(self) -> None:
        self.continuing = False

    def shown(self, line: str) -> bool:
        text = line.rstrip("\n")
        if EVENT_TAG in text:
            self.continuing = False
            return True
        if SEVERE.search(text) or TRACEBACK in text:
            self.continuing = True
            return True
        if self.continuing and text and not RECORD_START.match(text):
            return True
        self.continuing = False
        return False


def rotate(path: Path) -> None:
    """Keep the previous run's log as <name>.log.1; this run starts a fresh file."""
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.exists() and path.stat().st_size:
        path.replace(path.with_name(path.name + ".1"))


def tail(path: Path, lines: int = 20) -> list[str]:
    try:
        with path.open(errors="replace") as f:
            return list(deque(f, maxlen=lines))
    except FileNotFoundError:
        return []


class ProcessOutput:
    """One process's side of the terminal: its prefix, its filter and its log file."""

    def __init__(self, name: str, prefix: str, log_dir: Path = LOG_DIR, out=None) -> None:  # type: ignore[no-untyped-def]
        self.name = name
        self.prefix = prefix
        self.log_path = log_dir / f"{name}.log"
        self.filter = OutputFilter()
        self.out = out or sys.stdout
        rotate(self.log_path)

    def write(self, text: str) -> None:
        self.out.write(f"{self.prefix}{text.rstrip()}\n")
        self.out.flush()

    def on_line(self, line: str) -> None:
        if self.filter.shown(line):
            self.write(line)

    def started(self, pid: int | None) -> None:
        self.write(f"started (pid {pid}); everything it writes: {relative(self.log_path)}")

    def exited(self, code: int) -> None:
        """An unexpected exit: the last lines it wrote, which were probably hidden."""
        self.write(f"exited with code {code}; its last lines ({relative(self.log_path)}):")
        for line in tail(self.log_path):
            self.write(f"  {line}")


def relative(path: Path) -> str:
    try:
        return str(path.relative_to(ROOT))
    except ValueError:
        return str(path)
