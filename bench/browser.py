"""Headless Debian Chromium driven by Playwright, for the browser benchmarks and tests."""

from __future__ import annotations

import os
from typing import Any

CHROMIUM = os.environ.get("CHROMIUM", "/usr/bin/chromium")
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-gpu",
    "--no-first-run",
]


def launch_chromium(playwright: Any) -> Any:
    """The system Chromium, headless (Playwright's own browsers are not installed)."""
    return playwright.chromium.launch(executable_path=CHROMIUM, headless=True, args=CHROMIUM_ARGS)


def serve_app(database: str, logs_dir: Any, **env: str) -> Any:
    """The ASGI app under uvicorn (as `make run` serves it) on `database`, with no map
    tiles; its log in `logs_dir`/web.log. Returns the started Supervised process."""
    from runtime.processes import Supervised, free_port, python_env
    from workers.ground import web_argv

    port = free_port()
    environment = python_env(
        TEST_WORKER_DB_NAME=database, PYTHONUNBUFFERED="1", MAP_TILE_URL="", **env
    )
    server = Supervised("web", web_argv(port), environment, logs_dir / "web.log", port=port)
    return server.start().wait_ready(30)
