"""The README's pictures of the portal, taken by the browser tests that open each page when
DOCS_SCREENSHOTS names a folder (e.g. `DOCS_SCREENSHOTS=docs pytest tests/...browser.py`)."""

from __future__ import annotations

import os


def docs_screenshot(page, name: str, *, width: int = 1280, height: int = 900) -> None:  # type: ignore[no-untyped-def]
    folder = os.environ.get("DOCS_SCREENSHOTS")
    if not folder:
        return
    page.set_viewport_size({"width": width, "height": height})
    page.wait_for_timeout(500)  # let the map and charts redraw at the new size
    page.screenshot(path=f"{folder}/{name}.png", full_page=False)
