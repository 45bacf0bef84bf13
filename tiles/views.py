"""GET /tiles/<z>/<x>/<y>.png: a tile from the imported sets or the cache (or fetched
through the configured online source), with caching headers; 404 when nobody has it."""

from __future__ import annotations

import logging
from pathlib import Path

from django.conf import settings
from django.contrib.auth.decorators import login_required
from django.http import FileResponse, Http404, HttpRequest, HttpResponse, HttpResponseNotModified
from django.utils.http import http_date
from django.views.decorators.http import require_GET

from tiles import store, upstream

logger = logging.getLogger(__name__)


@require_GET
@login_required
def tile(request: HttpRequest, z: int, x: int, y: int, ext: str) -> HttpResponse:
    try:
        store.check_address(z, x, y)
    except store.TileError as exc:
        raise Http404(str(exc)) from exc
    path = store.find_tile(z, x, y)
    if path is not None and path.is_relative_to(store.cache_dir()):
        upstream.touch(path)  # the cache evicts the least recently used
    path = path or _from_upstream(request, z, x, y)
    if path is None:
        raise Http404(f"no tile {z}/{x}/{y}")
    return _file_response(request, path)


def _from_upstream(request: HttpRequest, z: int, x: int, y: int) -> Path | None:
    if not settings.TILE_UPSTREAM_URL:
        return None
    refused = upstream.refusal(request.user, z, x, y)
    if refused:
        logger.info("tile %s/%s/%s not fetched for %s: %s", z, x, y, request.user, refused)
        return None
    try:
        return upstream.fetch_and_keep(z, x, y)
    except upstream.UpstreamError as exc:
        logger.warning("tile %s/%s/%s not fetched: %s", z, x, y, exc)
        return None


def _file_response(request: HttpRequest, path: Path) -> HttpResponse:
    stat = path.stat()
    etag = f'"{stat.st_mtime_ns:x}-{stat.st_size:x}"'
    headers = {
        "ETag": etag,
        "Last-Modified": http_date(stat.st_mtime),
        "Cache-Control": f"private, max-age={int(settings.TILE_CACHE_MAX_AGE_S)}",
    }
    if request.headers.get("If-None-Match") == etag:
        response: HttpResponse = HttpResponseNotModified()
    else:
        ext = path.suffix.lstrip(".")
        response = FileResponse(path.open("rb"), content_type=store.CONTENT_TYPES[ext])
    for name, value in headers.items():
        response[name] = value
    return response
