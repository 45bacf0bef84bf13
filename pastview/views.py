"""The past-view page of one drone (the view itself is drawn by static/js/pastview.js)."""

from __future__ import annotations

import math
from typing import Any

from django.conf import settings
from django.contrib.auth.decorators import login_required
from django.http import Http404, HttpRequest, HttpResponse
from django.shortcuts import render

from fleet.models import Drone, Role
from fleet.permissions import require_role

from .consumers import settings_dict
from .evaluation import FUNCTIONS

# A 550-class frame when the drone's specs do not say (onboard/gear_example/specs.json).
DEFAULT_FRAME_MM = 550.0


def frame_box(specs: dict[str, Any]) -> dict[str, float]:
    """The drawn box in metres, with the real frame's proportions.

    FRAME_SIZE is the motor-to-motor diagonal in millimetres (a "550" hexacopter); the
    box is the square that diagonal spans, a fifth as tall.
    """
    try:
        diagonal = float(specs.get("FRAME_SIZE", DEFAULT_FRAME_MM)) / 1000.0
    except (TypeError, ValueError):
        diagonal = DEFAULT_FRAME_MM / 1000.0
    if not math.isfinite(diagonal) or not 0.05 <= diagonal <= 5.0:
        diagonal = DEFAULT_FRAME_MM / 1000.0
    side = diagonal / math.sqrt(2.0)
    return {"length": side, "width": side, "height": side / 5.0}


def function_catalogue() -> dict[str, dict[str, Any]]:
    """Every evaluation function with its parameters' defaults, for the selector."""
    return {name: cls().to_dict() for name, cls in FUNCTIONS.items()}


@login_required
def page(request: HttpRequest, drone_id: str) -> HttpResponse:
    drone = Drone.objects.for_user(request.user).select_related("organisation")
    drone = drone.filter(drone_id=drone_id).first()
    if drone is None:
        raise Http404("No such drone.")
    config = {
        "droneId": drone.drone_id,
        "canOperate": require_role(request.user, drone.organisation, Role.OPERATOR),
        "box": frame_box(drone.specs or {}),
        "settings": settings_dict(drone),
        "functions": function_catalogue(),
        "settingsUrl": f"/pastview/api/{drone.drone_id}/settings/",
        "socketPath": f"/ws/pastview/{drone.drone_id}/",
        "teleopHz": settings.PASTVIEW_TELEOP_HZ,
        "teleopFreshS": settings.PASTVIEW_TELEOP_FRESH_S,
    }
    return render(request, "pastview/view.html", {"drone": drone, "config": config})
