from __future__ import annotations

from django.contrib.auth.decorators import login_required
from django.http import Http404, HttpRequest, HttpResponse
from django.shortcuts import render

from fleet.models import Drone


@login_required
def overview(request: HttpRequest) -> HttpResponse:
    """Every drone of the organisation with its battery and link state."""
    organisation = request.organisation  # type: ignore[attr-defined]
    if organisation is None:
        raise Http404("You are not a member of any organisation.")
    drones = Drone.objects.filter(organisation=organisation)
    return render(request, "telemetry/overview.html", {"drones": drones})
