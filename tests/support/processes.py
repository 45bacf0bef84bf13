"""Stopping the subprocesses tests and benchmarks start."""

from __future__ import annotations

import subprocess


def stop_process(process: subprocess.Popen, timeout: float = 10.0) -> int:
    """Ask the process to end (SIGTERM), kill it if it has not within `timeout` s; its code."""
    if process.poll() is None:
        process.terminate()
        try:
            process.wait(timeout)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
    return process.returncode
