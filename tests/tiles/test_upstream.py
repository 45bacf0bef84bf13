"""The pass-through cache: off by default; when TILE_UPSTREAM_URL is set, a missing tile
is fetched once from that (here: a real local HTTP) server and kept for later, offline;
only for members of an organisation, where their envelope lets them fly, in a cache of
a stated size that drops the least recently used tiles."""

from __future__ import annotations

import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import pytest

from tests.tiles.mbtiles import colour_of, png

pytestmark = pytest.mark.django_db


class TileServer:
    """A tile server with tiles at every zoom but 12, counting what it was asked."""

    def __init__(self) -> None:
        self.requests: list[str] = []
        outer = self

        class Handler(BaseHTTPRequestHandler):
            def do_GET(self) -> None:  # noqa: N802
                outer.requests.append(self.path)
                z, x, y = (int(v) for v in self.path.strip("/").removesuffix(".png").split("/"))
                if z == 12:
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


# Where acme flies in these tests: a home in Lisbon, 1 km about it (the default distance).
LISBON = [38.73, -9.143]
INSIDE = "/tiles/16/31103/25108.png"  # 38.733-38.737 N, 9.146-9.141 W: 600 m from home
OUTSIDE = "/tiles/16/31120/25108.png"  # the same row, 9 km east


@pytest.fixture
def upstream(settings, tmp_path, world):  # type: ignore[no-untyped-def]
    server = TileServer()
    settings.TILES_DIR = str(tmp_path / "tiles")
    settings.MAP_TILE_URL = ""
    world.org.envelope = {"home": LISBON}
    world.org.save()
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


def cached(settings) -> list[str]:  # type: ignore[no-untyped-def]
    folder = Path(settings.TILES_DIR) / "cache"
    return sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*.png"))


def test_a_user_of_no_organisation_has_nothing_fetched(settings, upstream, client):
    from tests import factories

    settings.TILE_UPSTREAM_URL = upstream.url
    client.force_login(factories.person(None))
    assert client.get(INSIDE).status_code == 404
    assert client.get("/tiles/2/1/1.png").status_code == 404
    assert upstream.requests == [] and cached(settings) == []


def test_tiles_outside_the_organisations_envelope_are_not_fetched(settings, upstream, client, world):  # fmt: skip
    settings.TILE_UPSTREAM_URL = upstream.url
    client.force_login(world.viewer)
    assert client.get(OUTSIDE).status_code == 404
    client.force_login(world.outsider)  # globex has no home and no drone position
    assert client.get(INSIDE).status_code == 404
    assert upstream.requests == [] and cached(settings) == []
    world.other_drone.lat, world.other_drone.lon = 38.7345, -9.1435
    world.other_drone.save()  # now globex flies there too
    assert client.get(INSIDE).status_code == 200
    assert upstream.requests == [INSIDE.removeprefix("/tiles")]


def test_an_inclusion_fence_is_the_area(settings, upstream, client, world):
    settings.TILE_UPSTREAM_URL = upstream.url
    east = [[38.73, -9.06], [38.74, -9.06], [38.74, -9.045], [38.73, -9.045]]
    fence = {"polygons": [{"inclusion": True, "polygon": east, "version": 1}], "circles": []}
    world.org.envelope = {"geoFence": fence}
    world.org.save()
    client.force_login(world.viewer)
    assert client.get(INSIDE).status_code == 404
    assert client.get(OUTSIDE).status_code == 200


def test_zooms_above_the_limit_are_not_fetched_and_the_overview_is(settings, upstream, client, world):  # fmt: skip
    settings.TILE_UPSTREAM_URL = upstream.url
    settings.TILE_UPSTREAM_MAX_ZOOM = 15
    client.force_login(world.viewer)
    assert client.get(INSIDE).status_code == 404
    assert client.get("/tiles/3/1/2.png").status_code == 200  # South America: overview
    assert client.get("/tiles/8/1/2.png").status_code == 404  # not overview, not acme's
    assert upstream.requests == ["/3/1/2.png"]


def test_the_cache_keeps_its_cap_by_dropping_the_least_recently_used(
    settings, upstream, client, world
):
    settings.TILE_UPSTREAM_URL = upstream.url
    client.force_login(world.viewer)
    first, second, third = (f"/tiles/16/{x}/25108.png" for x in (31102, 31103, 31104))
    size = len(png(colour_of(16, 31103, 25108), 64))
    settings.TILE_CACHE_MAX_BYTES = 3 * size - 1
    for path in (first, second):
        assert client.get(path).status_code == 200
    assert client.get(first).status_code == 200  # served from the cache: now the newest
    assert len(upstream.requests) == 2
    assert client.get(third).status_code == 200
    assert cached(settings) == ["16/31102/25108.png", "16/31104/25108.png"]
    assert client.get(second).status_code == 200  # fetched again
    assert len(upstream.requests) == 4
