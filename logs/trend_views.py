"""The Logs pages over many flights: the fleet's trend of one check, one drone's trends
of every check, and two logs overlaid on one time axis with their parameters' diff."""

from __future__ import annotations

import uuid

from django.contrib.auth.decorators import login_required
from django.http import Http404, HttpRequest, HttpResponse
from django.shortcuts import render

from fleet.models import Drone
from fleet.tenancy import acting_organisation
from logs import trends
from logs.checks import CHECKS
from logs.compare_api import may_operate
from logs.models import FlightLog
from logs.trends_api import DEFAULT_CHECK, statistic


@login_required
def fleet_trends(request: HttpRequest) -> HttpResponse:
    """`?check=`: every drone of the acting organisation, its figures over its logs and
    whether its newest drifts."""
    organisation = acting_organisation(request)
    if organisation is None:
        raise Http404("You are not a member of any organisation.")
    check = request.GET.get("check") or DEFAULT_CHECK
    if check not in CHECKS:
        check = DEFAULT_CHECK
    drones = trends.fleet_trend(organisation, check)
    return render(
        request,
        "logs/trends.html",
        {
            "check": check,
            "checks": list(CHECKS),
            "drones": drones,
            "flagged": sum(bool(d["drift"]) for d in drones),
            "flights": sum(len(d["points"]) for d in drones),
            "statistic": statistic(),
            "chart": {"check": check, "drones": drones},
        },
    )


@login_required
def drone_trends(request: HttpRequest, drone_id: str) -> HttpResponse:
    drone = Drone.objects.for_user(request.user).filter(drone_id=drone_id).first()
    if drone is None:
        raise Http404("There is no such drone among yours.")
    found = trends.drone_trend(drone, CHECKS)
    return render(
        request,
        "logs/drone_trends.html",
        {
            "drone": drone,
            "checks": [{"name": name, **trend} for name, trend in found.items()],
            "statistic": statistic(),
            "chart": {"drone": drone.drone_id, "checks": found},
        },
    )


@login_required
def overlay(request: HttpRequest) -> HttpResponse:
    """`?ids=<a>,<b>`: the two logs on one time axis, aligned at take-off or by an offset
    (`?offset=` seconds added to the second), and their parameters' differences."""
    raw = [x for x in request.GET.get("ids", "").replace(" ", "").split(",") if x]
    try:
        ids = list(dict.fromkeys(uuid.UUID(x) for x in raw))
    except ValueError:
        raise Http404("Name two logs.") from None
    found = {log.pk: log for log in FlightLog.objects.for_user(request.user).filter(pk__in=ids)}
    if len(ids) != 2 or len(found) != 2:
        raise Http404("One of these logs does not exist or is not yours to see.")
    logs = [found[i] for i in ids]
    return render(
        request,
        "logs/overlay.html",
        {"logs": logs, "can_save_reference": may_operate(request.user, logs[0])},
    )
