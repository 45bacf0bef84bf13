"""`make run`'s terminal: real processes' output through scripts/runlog.py, as devrun.py
wires it: a line per process at its start, then warnings, errors and drone events only;
every line in the process's log file."""

from __future__ import annotations

import io
import sys
import urllib.error
import urllib.request
from pathlib import Path

import pytest

from runtime.processes import Supervised, free_port, python_env, wait_for
from scripts.runlog import ProcessOutput, rotate
from workers.ground import beat_argv, web_argv

ROOT = Path(__file__).resolve().parents[2]


def run(
    name: str, argv: list[str], log_dir: Path, **env: str
) -> tuple[Supervised, ProcessOutput, io.StringIO]:
    """`argv` supervised exactly as devrun.py's Foreground.start does it."""
    shown = io.StringIO()
    output = ProcessOutput(name, f"{name:<8}| ", log_dir, out=shown)
    environment = python_env(
        DJANGO_SETTINGS_MODULE="config.settings.test", PYTHONUNBUFFERED="1", **env
    )

    def exited(code: int) -> None:
        if not process.stopping:  # stopped by the test, as devrun does on Ctrl-C: no report
            output.exited(code)

    process = Supervised(
        name, argv, environment, log_path=output.log_path, on_line=output.on_line, on_exit=exited
    )
    process.stopping = False  # type: ignore[attr-defined]
    process.start()
    output.started(process.pid)
    return process, output, shown


def stop(process: Supervised) -> None:
    process.stopping = True  # type: ignore[attr-defined]
    process.stop(10)


def lines(shown: io.StringIO) -> list[str]:
    return shown.getvalue().splitlines()


def test_beat_says_it_started_and_nothing_about_the_tasks_it_sends(tmp_path):
    process, output, shown = run("beat", beat_argv(tmp_path / "schedule"), tmp_path)
    try:
        # The offline sweep is due every 2 s: several sends in the log file...
        assert wait_for(lambda: output.log_path.read_text().count("Sending due task") >= 2, 30)
    finally:
        stop(process)
    # ...and none on the terminal, which shows the start line alone.
    assert "Sending due task" not in shown.getvalue()
    assert lines(shown) == [
        f"beat    | started (pid {process.pid}); everything it writes: {output.log_path}"
    ]


def test_web_keeps_its_routine_lines_in_the_file_and_shows_warnings(tmp_path):
    port = free_port()
    process, output, shown = run("web", [sys.executable, *web_argv(port)[1:]], tmp_path)
    try:
        assert wait_for(lambda: process.alive and _get(port, "/accounts/login/") == 200, 30)
        assert _get(port, "/no-such-page/") == 404
        assert wait_for(lambda: "Not Found: /no-such-page/" in shown.getvalue(), 10)
    finally:
        stop(process)
    log = output.log_path.read_text()
    assert "Uvicorn running on" in log and "Application startup complete" in log
    assert "Uvicorn running on" not in shown.getvalue()
    assert [line for line in lines(shown) if "WARNING" in line] == [
        "web     | "
        + next(line for line in log.splitlines() if "Not Found: /no-such-page/" in line)
    ]


def _get(port: int, path: str) -> int | None:
    try:
        with urllib.request.urlopen(f"http://127.0.0.1:{port}{path}", timeout=2) as response:
            return response.status
    except urllib.error.HTTPError as exc:
        return exc.code
    except OSError:
        return None


EVENTS = """
import django
django.setup()
from fleet.models import ConnectionEvent
from fleet.signals import drones_came_online, drones_went_offline
drones_came_online.send(sender=ConnectionEvent, organisation_ids=set(), drone_ids=["ACME_1"])
drones_went_offline.send(sender=ConnectionEvent, drone_ids=["ACME_2", "ACME_3"])
import logging
logging.getLogger("fleet").info("routine detail nobody needs on the terminal")
raise ValueError("the drone sent something odd")
"""


@pytest.mark.django_db(transaction=True)
def test_drone_events_and_a_crash_with_its_traceback_are_shown(tmp_path):
    from django.db import connection

    database = connection.settings_dict["NAME"]
    process, output, shown = run(
        "gateway", [sys.executable, "-c", EVENTS], tmp_path, TEST_WORKER_DB_NAME=database
    )
    assert wait_for(lambda: not process.alive and "exited with code 1" in shown.getvalue(), 60)
    text = shown.getvalue()
    assert "[event] online: ACME_1" in text and "[event] offline: ACME_2, ACME_3" in text
    assert "routine detail" not in text.split("its last lines")[0]
    # The traceback in full, then (the process died) the last lines of its log.
    assert "Traceback (most recent call last)" in text
    assert "ValueError: the drone sent something odd" in text
    assert "routine detail" in output.log_path.read_text()


def test_each_run_starts_a_fresh_log_and_keeps_the_previous_one(tmp_path):
    log = tmp_path / "web.log"
    log.write_text("last run\n")
    rotate(log)
    assert not log.exists() and (tmp_path / "web.log.1").read_text() == "last run\n"
