"""What every map in the portal draws underneath: the tile layer (the portal's own tiles,
or MAP_TILE_URL when a site points at another server) or, with no tiles at all, nothing,
so the pages draw their scale and grid alone and ask for no tile that would fail."""

from __future__ import annotations

from django.conf import settings
from django.db.models import Max, Min
from django.http import HttpRequest
from django.urls import reverse

from tiles.models import TileSet

# The Web Mercator limits Leaflet draws tiles within.
WORLD = (-180.0, -85.0511, 180.0, 85.0511)


def map_layer() -> dict[str, object]:
    """{url, attribution, minZoom, maxNativeZoom, bounds} for static/js/map_base.js."""
    if settings.MAP_TILE_URL:
        return _layer(settings.MAP_TILE_URL, settings.MAP_TILE_ATTRIBUTION, 0, 19, WORLD)
    local = reverse("tiles:tile", args=[0, 0, 0, "png"]).replace("0/0/0.png", "{z}/{x}/{y}.png")
    if settings.TILE_UPSTREAM_URL:
        attribution = settings.TILE_UPSTREAM_ATTRIBUTION
        return _layer(local, attribution, 0, int(settings.TILE_UPSTREAM_MAX_ZOOM), WORLD)
    sets = TileSet.objects.aggregate(
        lo=Min("min_zoom"), hi=Max("max_zoom"), w=Min("west"), s=Min("south"),
        e=Max("east"), n=Max("north"),
    )  # fmt: skip
    if sets["lo"] is None:
        return {"url": ""}
    names = TileSet.objects.exclude(attribution="").values_list("attribution", flat=True)
    bounds = (sets["w"], sets["s"], sets["e"], sets["n"])
    return _layer(local, " · ".join(sorted(set(names))), sets["lo"], sets["hi"], bounds)


def _layer(url: str, attribution: str, lo: int, hi: int, bounds: tuple) -> dict[str, object]:
    west, south, east, north = bounds
    return {
        "url": url,
        "attribution": attribution,
        "minZoom": lo,
        "maxNativeZoom": hi,
        "bounds": [[south, west], [north, east]],
    }


def map_layer_context(request: HttpRequest) -> dict[str, object]:
    """Template context: `map_layer` for base.html's json_script (signed-in pages only)."""
    if not getattr(request, "user", None) or not request.user.is_authenticated:
        return {}
    return {"map_layer": map_layer()}
