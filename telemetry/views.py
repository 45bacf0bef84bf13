"""Telemetry pages: the organisation overview, a drone's dashboard, the ingest status."""

from __future__ import annotations

from datetime import UTC, datetime

from django.contrib.auth.decorators import login_required
from django.http import Http404, HttpRequest, HttpResponse
from django.shortcuts import get_object_or_404, render

from fleet.models import Drone
from workers import operations

from . import queries, status

# What the overview shows per drone: battery and the flight controller's link statistics.
OVERVIEW_OBJECTS = ["FlightBatteryState", "FlightTelemetryStats", "GCSTelemetryStats"]


def _organisation_or_404(request: HttpRequest):  # type: ignore[no-untyped-def]
    if request.organisation is None:  # type: ignore[attr-defined]
        raise Http404("You are not a member of any organisation.")
    return request.organisation  # type: ignore[attr-defined]


@login_required
def overview(request: HttpRequest) -> HttpResponse:
    """Every drone of the organisation with its battery and link quality."""
    organisation = _organisation_or_404(request)
    drones = list(Drone.objects.filter(organisation=organisation))
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
    return render(request, "telemetry/overview.html", {"rows": rows})


@login_required
def dashboard(request: HttpRequest, drone_id: str) -> HttpResponse:
    organisation = _organisation_or_404(request)
    drone = get_object_or_404(Drone, organisation=organisation, drone_id=drone_id)
    return render(request, "telemetry/dashboard.html", {"drone": drone})


@login_required
def ingest_status(request: HttpRequest) -> HttpResponse:
    """The ingest counters, and for operators the figures to watch (read by the page)."""
    return render(
        request,
        "telemetry/status.html",
        {"status": status.ingest_status(), "show_watch": operations.may_see(request.user)},
    )
