"""Telemetry pages: the organisation overview, a drone's dashboard, the ingest status, and
the operations page (every process instance and the figures to watch) with its JSON API."""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Any

from django.contrib.auth.decorators import login_required
from django.core.exceptions import PermissionDenied
from django.core.paginator import Paginator
from django.http import Http404, HttpRequest, HttpResponse
from django.shortcuts import get_object_or_404, render
from drf_spectacular.types import OpenApiTypes
from drf_spectacular.utils import extend_schema
from rest_framework.decorators import api_view
from rest_framework.request import Request
from rest_framework.response import Response

from fleet import listing
from fleet.models import Drone, Membership, Role
from fleet.tenancy import acting_organisation
from workers import operations
from workers.ingest_status import drone_refusals
from workers.ingest_status import ingest_status as read_ingest_status

from . import queries

# What the overview shows per drone: battery and the flight controller's link statistics.
OVERVIEW_OBJECTS = ["FlightBatteryState", "FlightTelemetryStats", "GCSTelemetryStats"]


def _organisation_or_404(request: HttpRequest):  # type: ignore[no-untyped-def]
    if acting_organisation(request) is None:
        raise Http404("You are not a member of any organisation.")
    return acting_organisation(request)


@login_required
def overview(request: HttpRequest) -> HttpResponse:
    """The organisation's drones with their battery and link quality, a page at a time,
    searchable and filtered like the fleet table (fleet.listing)."""
    organisation = _organisation_or_404(request)
    try:
        query = listing.TableQuery.from_params(request.GET)
    except listing.BadQuery:
        query = listing.TableQuery()
    matching = listing.matching(Drone.objects.filter(organisation=organisation), query)
    page = Paginator(matching.order_by("drone_id"), query.page_size).get_page(query.page)
    drones = list(page.object_list)
    latest = queries.latest_for_drones([d.pk for d in drones], OVERVIEW_OBJECTS)
    rows = []
    for drone in drones:
        objects = latest.get(drone.pk, {})
        battery = objects.get("FlightBatteryState", {}).get("fields", {})
        link = objects.get("FlightTelemetryStats", {}).get("fields", {})
        last = max((o["ts"] for o in objects.values()), default=None)
        rows.append(
            {
                "drone": drone,
                "battery": battery,
                "link": link,
                "last": datetime.fromtimestamp(last, UTC) if last is not None else None,
            }
        )
    params = request.GET.copy()
    params.pop("page", None)
    context = {
        "rows": rows,
        "page": page,
        "q": query.search,
        "filters": [(n, n.replace("_", " "), n in query.filters) for n in listing.FILTERS],
        "keep": params.urlencode(),
        # The page's drones, live: their state and battery as their heartbeats arrive.
        "overview_config": {
            "socketPath": f"/ws/fleet/?org={organisation.slug}"
            f"&drone={','.join(d.drone_id for d in drones)}",
            "drones": [],
        },
    }
    return render(request, "telemetry/overview.html", context)


@login_required
def dashboard(request: HttpRequest, drone_id: str) -> HttpResponse:
    organisation = _organisation_or_404(request)
    drone = get_object_or_404(Drone, organisation=organisation, drone_id=drone_id)
    return render(request, "telemetry/dashboard.html", {"drone": drone})


@login_required
def ingest_status(request: HttpRequest) -> HttpResponse:
    """The ingest counters, the messages refused per drone (the user's drones; staff see
    every drone), and for operators the figures to watch (read by the page)."""
    user = request.user
    visible = None
    if not user.is_staff:
        visible = set(Drone.objects.for_user(user).values_list("drone_id", flat=True))
    return render(
        request,
        "telemetry/status.html",
        {
            "status": read_ingest_status(),
            "refusals": drone_refusals(visible),
            "show_watch": may_see(user),
        },
    )


# -- operations -------------------------------------------------------------------------------

REFRESH_S = 5


def may_see(user: Any) -> bool:
    """Operators and admins (of any of their organisations) and staff see the operations
    figures; viewers do not: host names, pids and queue depths are the platform's, not
    their organisation's."""
    if not getattr(user, "is_authenticated", False):
        return False
    if user.is_staff:
        return True
    return Membership.objects.filter(user=user, role__in=[Role.OPERATOR, Role.ADMIN]).exists()


@login_required
def operations_page(request: HttpRequest) -> HttpResponse:
    if not may_see(request.user):
        raise PermissionDenied("The operations page is for operators and admins.")
    return render(
        request,
        "operations/index.html",
        {"figures": operations.gather(), "refresh_s": REFRESH_S},
    )


@extend_schema(
    summary="Process instances, queues, broker and the figures to watch",
    responses={200: OpenApiTypes.OBJECT},
)
@api_view(["GET"])
def operations_api(request: Request) -> Response:
    if not may_see(request.user):
        raise PermissionDenied("The operations figures are for operators and admins.")
    return Response(operations.gather())
