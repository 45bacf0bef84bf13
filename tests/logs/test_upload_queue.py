"""The Logs page sends a user's files no faster than the server takes them: dropped
together, they wait in the page for a free place (UPLOAD_MAX_CONCURRENT) instead of
being refused with 429."""

from __future__ import annotations

import pytest
from playwright.sync_api import expect

from tests.conftest import login

pytestmark = [pytest.mark.browser, pytest.mark.e2e, pytest.mark.usefixtures("logs_settings")]


def test_files_dropped_together_wait_for_a_free_place(world_tx, page, tmp_path, logs_dir):
    from django.db import connection

    from tests.logs.conftest import QUEUE
    from tests.support.live import LiveServer

    env = {"LOGS_DIR": str(logs_dir), "LOGS_IMPORT_QUEUE": QUEUE, "UPLOAD_MAX_CONCURRENT": "1"}
    server = LiveServer(connection.settings_dict["NAME"], extra_env=env)
    files = []
    for i in range(5):
        files.append(tmp_path / f"photo-{i}.jpg")
        files[-1].write_bytes(b"\xff\xd8\xff\xe0 not a flight log" * 20_000)
    try:
        login(page, server, "operator")
        page.goto(f"{server.url}/logs/")
        page.set_input_files("#log-file", [str(f) for f in files])
        items = page.locator("#uploads li.failed")
        expect(items).to_have_count(5, timeout=20_000)
        # Each reached the view, which judged the file; none was turned away at the door.
        expect(items.filter(has_text="is not a flight log format we can read")).to_have_count(5)
    finally:
        server.stop()
