"""Portal pages of the fleet. Each page acts for the request's current organisation."""

from __future__ import annotations

from django.conf import settings
from django.contrib.auth.decorators import login_required
from django.http import Http404, HttpRequest, HttpResponse
from django.shortcuts import get_object_or_404, redirect, render
from django.views.decorators.http import require_POST

from .models import Drone, Membership, Role
from .serializers import DroneDetailSerializer, DroneSerializer
from .tenancy import SESSION_KEY, role_in


def _organisation_or_404(request: HttpRequest):  # type: ignore[no-untyped-def]
    if request.organisation is None:  # type: ignore[attr-defined]
        raise Http404("You are not a member of any organisation.")
    return request.organisation  # type: ignore[attr-defined]


@login_required
def index(request: HttpRequest) -> HttpResponse:
    organisation = _organisation_or_404(request)
    drones = Drone.objects.filter(organisation=organisation).select_related("organisation")
    return render(
        request,
        "fleet/index.html",
        {
            "drones": drones,
            "fleet_config": _live_config(request, DroneSerializer(drones, many=True).data),
        },
    )


def _live_config(request: HttpRequest, drones: object) -> dict:
    """What the page scripts need: the map tiles, the websocket, the initial state."""
    return {
        "tileUrl": settings.MAP_TILE_URL,
        "attribution": settings.MAP_TILE_ATTRIBUTION,
        "socketPath": f"/ws/fleet/?org={request.organisation.slug}",  # type: ignore[attr-defined]
        "droneUrl": "/drones/__ID__/",
        "drones": drones,
    }


@login_required
def drone_detail(request: HttpRequest, drone_id: str) -> HttpResponse:
    organisation = _organisation_or_404(request)
    drone = get_object_or_404(Drone, organisation=organisation, drone_id=drone_id)
    events = drone.connection_events.all()[:50]
    commands = drone.commands.select_related("user")[:20]
    config = _live_config(request, [DroneDetailSerializer(drone).data])
    config["commandUrl"] = f"/api/v1/drones/{drone.drone_id}/commands/"
    return render(
        request,
        "fleet/drone.html",
        {
            "drone": drone,
            "connection_events": events,
            "commands": commands,
            "fleet_config": config,
        },
    )


@login_required
@require_POST
def switch_organisation(request: HttpRequest) -> HttpResponse:
    slug = request.POST.get("organisation", "")
    if not Membership.objects.for_user(request.user).filter(organisation__slug=slug).exists():
        raise Http404("No such organisation.")
    request.session[SESSION_KEY] = slug
    return redirect("fleet:index")


@login_required
def envelope(request: HttpRequest) -> HttpResponse:
    """The organisation's flight envelope: its fence on a map, editable by admins."""
    organisation = _organisation_or_404(request)
    membership = role_in(request.user, organisation)
    config = {
        "tileUrl": settings.MAP_TILE_URL,
        "attribution": settings.MAP_TILE_ATTRIBUTION,
        "apiUrl": f"/api/v1/organisations/{organisation.slug}/envelope/",
        "editable": bool(membership and membership.allows(Role.ADMIN)),
    }
    return render(request, "fleet/envelope.html", {"envelope_config": config})
