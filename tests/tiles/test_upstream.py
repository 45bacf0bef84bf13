"""The pass-through cache: off by default; when TILE_UPSTREAM_URL is set, a missing tile
is fetched once from that (here: a real local HTTP) server and kept for later, offline."""

from __future__ import annotations

import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import pytest

from tests.tiles.mbtiles import colour_of, png

pytestmark = pytest.mark.django_db


class TileServer:
    """A tile server with tiles at zoom 16 only, counting what it was asked."""

    def __init__(self) -> None:
        self.requests: list[str] = []
        outer = self

        class Handler(BaseHTTPRequestHandler):
            def do_GET(self) -> None:  # noqa: N802
                outer.requests.append(self.path)
                z, x, y = (int(v) for v in self.path.strip("/").removesuffix(".png").split("/"))
                if z != 16:
                    self.send_error(404)
                    return
                body = png(colour_of(z, x, y), 64)
                self.send_response(200)
                self.send_header("Content-Type", "image/png")
                self.send_header("Content-Length", str(len(body)))
                self.end_headers()
                self.wfile.write(body)

            def log_message(self, *args) -> None:  # type: ignore[no-untyped-def]
                pass

        self.server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.url = f"http://127.0.0.1:{self.server.server_address[1]}/{{z}}/{{x}}/{{y}}.png"
        threading.Thread(target=self.server.serve_forever, daemon=True).start()

    def stop(self) -> None:
        self.server.shutdown()
        self.server.server_close()


@pytest.fixture
def upstream(settings, tmp_path):  # type: ignore[no-untyped-def]
    server = TileServer()
    settings.TILES_DIR = str(tmp_path / "tiles")
    settings.MAP_TILE_URL = ""
    yield server
    server.stop()


def test_no_upstream_by_default(settings, upstream, client, world):
    settings.TILE_UPSTREAM_URL = ""
    client.force_login(world.viewer)
    assert client.get("/tiles/16/31103/25108.png").status_code == 404
    assert upstream.requests == []


def test_a_fetched_tile_is_kept_and_served_when_the_source_is_gone(
    settings, upstream, client, world
):
    settings.TILE_UPSTREAM_URL = upstream.url
    client.force_login(world.viewer)
    response = client.get("/tiles/16/31103/25108.png")
    assert response.status_code == 200
    assert b"".join(response.streaming_content) == png(colour_of(16, 31103, 25108), 64)
    assert (Path(settings.TILES_DIR) / "cache/16/31103/25108.png").is_file()
    upstream.stop()
    again = client.get("/tiles/16/31103/25108.png")
    assert again.status_code == 200 and upstream.requests == ["/16/31103/25108.png"]


def test_tiles_the_source_does_not_have_or_cannot_send_are_404(settings, upstream, client, world):
    settings.TILE_UPSTREAM_URL = upstream.url
    client.force_login(world.viewer)
    assert client.get("/tiles/12/1944/1547.png").status_code == 404
    upstream.stop()
    assert client.get("/tiles/16/1/1.png").status_code == 404
    assert not (Path(settings.TILES_DIR) / "cache/12").exists()
