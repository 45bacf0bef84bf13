"""Portal pages of the fleet. Each page acts for the request's current organisation."""

from __future__ import annotations

from django.conf import settings
from django.contrib.auth.decorators import login_required
from django.http import Http404, HttpRequest, HttpResponse, JsonResponse
from django.shortcuts import get_object_or_404, redirect, render
from django.urls import reverse
from django.views.decorators.http import require_POST

from . import airworthiness, listing, remote_id
from .models import Drone, Membership, Role
from .serializers import DroneDetailSerializer
from .state import LABELS, describe
from .tenancy import SESSION_KEY, acting_organisation, role_in


def _organisation_or_404(request: HttpRequest):  # type: ignore[no-untyped-def]
    if acting_organisation(request) is None:
        raise Http404("You are not a member of any organisation.")
    return acting_organisation(request)


@login_required
def index(request: HttpRequest) -> HttpResponse:
    """The map and a table page: the drones themselves come from the table API and the
    socket, so the page costs the same with 10 drones or 10 000."""
    organisation = _organisation_or_404(request)
    config = _live_config(request, [])
    config.update(
        tableUrl=reverse("fleet:table"),
        filters=list(listing.FILTERS),
        states=LABELS,
        pageSize=listing.PAGE_SIZE,
    )
    return render(
        request,
        "fleet/index.html",
        {
            "has_drones": Drone.objects.filter(organisation=organisation).exists(),
            "filters": [(name, name.replace("_", " ")) for name in listing.FILTERS],
            "fleet_config": config,
        },
    )


@login_required
def drone_table(request: HttpRequest) -> JsonResponse:
    """`GET ?q=&filter=online,airborne&page=2&page_size=50`: one page of the table."""
    organisation = _organisation_or_404(request)
    try:
        query = listing.TableQuery.from_params(request.GET)
    except listing.BadQuery as exc:
        return JsonResponse({"error": str(exc)}, status=400)
    return JsonResponse(listing.table_page(organisation.pk, query))


def _live_config(request: HttpRequest, drones: object, drone_id: str | None = None) -> dict:
    """What the page scripts need: the map tiles, the websocket, the initial state."""
    socket = f"/ws/fleet/?org={acting_organisation(request).slug}"  # type: ignore[union-attr]
    return {
        "tileUrl": settings.MAP_TILE_URL,
        "attribution": settings.MAP_TILE_ATTRIBUTION,
        "socketPath": socket if drone_id is None else f"{socket}&drone={drone_id}",
        "droneUrl": "/drones/__ID__/",
        "missionUrl": "/missions/__ID__/",
        "drones": drones,
    }


@login_required
def drone_detail(request: HttpRequest, drone_id: str) -> HttpResponse:
    organisation = _organisation_or_404(request)
    drone = get_object_or_404(Drone, organisation=organisation, drone_id=drone_id)
    events = drone.connection_events.all()[:50]
    commands = drone.commands.select_related("user")[:20]
    config = _live_config(
        request, [describe(dict(DroneDetailSerializer(drone).data))], drone.drone_id
    )
    config["commandUrl"] = f"/api/v1/drones/{drone.drone_id}/commands/"
    return render(
        request,
        "fleet/drone.html",
        {
            "drone": drone,
            "connection_events": events,
            "commands": commands,
            "state": config["drones"][0]["state"],
            "state_label": LABELS[config["drones"][0]["state"]],
            "fleet_config": config,
            "airworthiness": airworthiness.verdict(drone),
            "remote_id_health": airworthiness.remote_id_health(drone),
            "declared": remote_id.declared_labels(drone),
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
