"""The video wall: every live stream of the acting organisation's drones on one page."""

from __future__ import annotations

from django.contrib.auth.decorators import login_required
from django.http import Http404, HttpRequest, HttpResponse
from django.shortcuts import render

from fleet.models import Drone
from fleet.tenancy import acting_organisation

from . import client

# Each tile is a viewer session on the media server: a wall shows at most this many.
WALL_MAX_STREAMS = 12


@login_required
def wall(request: HttpRequest) -> HttpResponse:
    organisation = acting_organisation(request)
    if organisation is None:
        raise Http404("You are not a member of any organisation.")
    try:
        live = client.live_streams()
        unavailable = False
    except client.MediaServerUnavailable:
        live, unavailable = {}, True
    drones = list(
        Drone.objects.filter(organisation=organisation, drone_id__in=list(live)).order_by(
            "drone_id"
        )[:WALL_MAX_STREAMS]
    )
    return render(
        request,
        "livevideo/wall.html",
        {"drones": drones, "unavailable": unavailable, "limit": WALL_MAX_STREAMS},
    )
