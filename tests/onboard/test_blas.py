"""Agent and ground processes multiply on one BLAS thread: OpenBLAS's idle workers spin."""

import os
import subprocess
import sys

import pytest

from onboard.blas import THREAD_VARIABLES, one_thread
from tests.support.paths import ROOT

# The synthetic camera's product: enough rows for OpenBLAS to hand work to its threads.
PRODUCT = (
    "import numpy as np, os; "
    "np.ones((76800, 3), np.float32) @ np.eye(3, dtype=np.float32); "
    "print(len(os.listdir(f'/proc/{os.getpid()}/task')))"
)


def _threads_after(first_import: str) -> int:
    env = {k: v for k, v in os.environ.items() if k not in THREAD_VARIABLES}
    env["DJANGO_SETTINGS_MODULE"] = "config.settings.test"
    done = subprocess.run(
        [sys.executable, "-c", f"import {first_import}; {PRODUCT}"],
        env=env,
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
    )
    return int(done.stdout.strip())


@pytest.mark.parametrize("package", ["onboard", "config"])
def test_a_process_of_ours_has_no_blas_worker_threads(package):
    assert _threads_after(package) == 1


def test_a_thread_count_the_user_set_is_kept(monkeypatch):
    monkeypatch.setenv("OPENBLAS_NUM_THREADS", "4")
    for name in THREAD_VARIABLES[1:]:
        monkeypatch.delenv(name, raising=False)
    one_thread()
    assert os.environ["OPENBLAS_NUM_THREADS"] == "4"
    assert all(os.environ[name] == "1" for name in THREAD_VARIABLES[1:])
