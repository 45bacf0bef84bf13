"""A process stops on SIGTERM or SIGINT whatever its main thread was doing.

A `threading.Event` set from a signal handler deadlocks when the signal arrives while the
main thread is inside that event's own `wait` (the handler runs in the main thread and
waits for the lock the main thread holds): `manage.py pastview` once never exited after a
SIGTERM under load. Handlers set a flag instead (runtime/stopsignal.py; the agent keeps its
own, since the drone package imports nothing of runtime)."""

from __future__ import annotations

import ast
import os
import signal
import threading
import time
from pathlib import Path

from runtime.stopsignal import StopSignal

ROOT = Path(__file__).resolve().parents[1]
SOURCES = ("config", "firmware", "onboard", "runtime", "scripts", "workers", "bench")


def test_a_signal_ends_the_wait_at_once():
    previous = signal.getsignal(signal.SIGUSR1)
    stop = StopSignal().install((signal.SIGUSR1,))
    try:
        timer = threading.Timer(0.1, os.kill, (os.getpid(), signal.SIGUSR1))
        began = time.monotonic()
        timer.start()
        assert stop.wait(10)
        # Within a few of its sleep steps (0.05 s) of the signal, with room for a busy machine:
        # measured 0.10 s (the timer's own 0.1 s) quiet and with four busy processes on two cores.
        assert time.monotonic() - began < 2
        assert stop.is_set() and stop.signum == signal.SIGUSR1
    finally:
        signal.signal(signal.SIGUSR1, previous)


def test_a_wait_without_a_signal_times_out_and_set_ends_it():
    stop = StopSignal()
    assert stop.wait(0.05) is False
    stop.set()
    assert stop.wait(0.0) is True


def _handlers_setting_an_event(path: Path) -> list[str]:
    """`signal.signal(..., handler)` calls whose handler calls `.set()`: a lambda, or a
    function of the same module."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    functions = {
        node.name: node
        for node in ast.walk(tree)
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef)
    }
    found = []
    for node in ast.walk(tree):
        if not (
            isinstance(node, ast.Call)
            and isinstance(node.func, ast.Attribute)
            and node.func.attr == "signal"
            and isinstance(node.func.value, ast.Name)
            and node.func.value.id == "signal"
            and len(node.args) == 2
        ):
            continue
        handler = node.args[1]
        if isinstance(handler, ast.Name):
            handler = functions.get(handler.id, handler)
        calls = [c for c in ast.walk(handler) if isinstance(c, ast.Call)]
        if any(isinstance(c.func, ast.Attribute) and c.func.attr == "set" for c in calls):
            found.append(f"{path.relative_to(ROOT)}:{node.lineno}")
    return found


def test_no_signal_handler_sets_an_event():
    paths = [ROOT / "manage.py"]
    paths += [p for folder in SOURCES for p in sorted((ROOT / folder).rglob("*.py"))]
    for app in ROOT.iterdir():
        paths += sorted(app.glob("management/commands/*.py"))
    offenders = [hit for path in paths for hit in _handlers_setting_an_event(path)]
    assert offenders == [], offenders
