"""`/pastview/api/<drone_id>/settings/`: read (members) and change (operators) a drone's
past-view settings. Errors use the API's one shape (config.api)."""

from __future__ import annotations

import math

from drf_spectacular.types import OpenApiTypes
from drf_spectacular.utils import extend_schema
from rest_framework import exceptions
from rest_framework.decorators import api_view
from rest_framework.request import Request
from rest_framework.response import Response

from fleet.models import Drone, Role
from fleet.permissions import require_role

from .models import ViewSettings
from .selection import PastViewSettings

CAMERA_LIMITS = {"fov_deg": (1.0, 170.0), "pitch_down_deg": (-90.0, 90.0)}


def _camera(data: object, row: ViewSettings) -> dict[str, float]:
    current = {"fov_deg": row.camera_fov_deg, "pitch_down_deg": row.camera_pitch_down_deg}
    if data is None:
        return current
    if not isinstance(data, dict):
        raise exceptions.ValidationError({"camera": ["Must be an object."]})
    unknown = sorted(set(data) - set(CAMERA_LIMITS))
    if unknown:
        raise exceptions.ValidationError({f"camera.{k}": ["Unknown field."] for k in unknown})
    out = dict(current)
    for name, (lo, hi) in CAMERA_LIMITS.items():
        if name not in data:
            continue
        value = data[name]
        if (
            isinstance(value, bool)
            or not isinstance(value, int | float)
            or not math.isfinite(value)
        ):
            raise exceptions.ValidationError({f"camera.{name}": ["Must be a number."]})
        if not lo <= value <= hi:
            raise exceptions.ValidationError(
                {f"camera.{name}": [f"Must be within {lo:g}..{hi:g}."]}
            )
        out[name] = float(value)
    return out


@extend_schema(request=OpenApiTypes.OBJECT, responses=OpenApiTypes.OBJECT)
@api_view(["GET", "PUT"])
def view_settings(request: Request, drone_id: str) -> Response:
    """GET the settings; PUT ``{"evaluation": {"function": ..., coefficients...}, "camera":
    {...}, "capacity": ..., ...}`` (missing keys keep their defaults, the camera its value)."""
    drone = Drone.objects.for_user(request.user).select_related("organisation")
    drone = drone.filter(drone_id=drone_id).first()
    if drone is None:
        raise exceptions.NotFound(f"Unknown drone {drone_id!r}.")
    row = ViewSettings.objects.filter(drone=drone).first() or ViewSettings(drone=drone)
    if request.method == "GET":
        return Response(row.to_dict())
    if not require_role(request.user, drone.organisation, Role.OPERATOR):
        raise exceptions.PermissionDenied("Only operators and admins may change the view.")
    if not isinstance(request.data, dict):
        raise exceptions.ValidationError({"non_field_errors": ["Send a JSON object."]})
    data = dict(request.data)
    camera = _camera(data.pop("camera", None), row)
    evaluation = data.get("evaluation")
    if isinstance(evaluation, dict) and evaluation.get("function", "spirit") == "spirit":
        # SPIRIT's centrality is measured along the camera's axis: keep the two in step.
        data["evaluation"] = {**evaluation, "camera_pitch_down_deg": camera["pitch_down_deg"]}
    try:
        parsed = PastViewSettings.from_dict(data)
    except (ValueError, TypeError) as exc:
        raise exceptions.ValidationError({"non_field_errors": [str(exc)]}) from None
    row.settings = parsed.to_dict()
    row.camera_fov_deg = camera["fov_deg"]
    row.camera_pitch_down_deg = camera["pitch_down_deg"]
    row.updated_by = request.user
    row.save()
    return Response(row.to_dict())
