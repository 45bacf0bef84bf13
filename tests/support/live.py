"""A live ASGI server (uvicorn, the same app `make run` serves) on the test database, and
the headless Chromium (bench.browser), for browser and end-to-end tests."""

from __future__ import annotations

from pathlib import Path

from django.conf import settings

from bench.browser import launch_chromium
from runtime.processes import Supervised, free_port, python_env
from workers.ground import web_argv


class LiveServer:
    """The ASGI app under uvicorn on a free port, reading `database_name`."""

    def __init__(self, database_name: str, extra_env: dict[str, str] | None = None):
        self.port = free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        env = python_env(
            DJANGO_SETTINGS_MODULE="config.settings.test",
            TEST_WORKER_DB_NAME=database_name,
            PYTHONUNBUFFERED="1",
            **(extra_env or {}),
        )
        # The test profile's folder of this pytest worker (config/settings/test.py).
        log = Path(settings.TEST_DATA_DIR) / f"live-{self.port}.log"
        self.process = Supervised("live server", web_argv(self.port), env, log, port=self.port)
        self.process.start().wait_ready(30)

    def stop(self) -> None:
        self.process.stop(10)


__all__ = ["LiveServer", "launch_chromium"]
