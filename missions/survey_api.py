"""REST: survey planning from a camera — the spacings, the waypoints and, per drone, the
distance, time, photos and battery the survey would take, before anything is sent."""

from __future__ import annotations

from typing import Any

from django.conf import settings
from drf_spectacular.utils import extend_schema, inline_serializer
from rest_framework import serializers
from rest_framework.decorators import api_view, permission_classes
from rest_framework.permissions import IsAuthenticated
from rest_framework.request import Request
from rest_framework.response import Response

from fleet.envelopes import home_of, organisation_envelope
from fleet.models import Drone, Organisation
from fleet.tenancy import current_membership
from missions import planning, survey
from missions.api import Refused

SurveyRequest = inline_serializer(
    "SurveyRequest",
    {
        "vertices": serializers.ListField(child=serializers.ListField()),
        "camera": serializers.JSONField(help_text="a preset name or the sensor and image sizes"),
        "overlap": serializers.FloatField(help_text="forward overlap, 0–0.95"),
        "sidelap": serializers.FloatField(help_text="side overlap, 0–0.95"),
        "height_m": serializers.FloatField(required=False),
        "gsd_cm": serializers.FloatField(required=False, help_text="wanted cm per pixel"),
        "speed_m_s": serializers.FloatField(required=False),
        "drones": serializers.ListField(child=serializers.CharField(), required=False),
        "home": serializers.ListField(child=serializers.FloatField(), required=False),
    },
)


def _organisation(request: Request) -> Organisation:
    membership = current_membership(request)
    if membership is None:
        raise Refused("organisation", "you are not a member of any organisation", 403)
    return membership.organisation


@extend_schema(responses=inline_serializer("SurveyCameras", {"presets": serializers.JSONField()}))
@api_view(["GET"])
@permission_classes([IsAuthenticated])
def cameras(request: Request) -> Response:
    """The camera presets, and the one each of the organisation's drones carries."""
    drones = Drone.objects.filter(organisation=_organisation(request)).only("drone_id", "sensors")
    carried = {
        d.drone_id: survey.preset_for(str((d.sensors or {}).get("CAMERA", ""))) for d in drones
    }
    return Response(
        {
            "presets": [c.to_dict() for c in survey.PRESETS.values()],
            "drones": {k: v for k, v in carried.items() if v},
        }
    )


@extend_schema(
    request=SurveyRequest,
    responses=inline_serializer("Survey", {"geometry": serializers.JSONField()}),
)
@api_view(["POST"])
@permission_classes([IsAuthenticated])
def plan(request: Request) -> Response:
    """Camera and overlaps → height, spacings and waypoints; estimates per drone."""
    body = request.data if isinstance(request.data, dict) else {}
    organisation = _organisation(request)
    try:
        camera = survey.camera_from(body.get("camera"))
        geometry = survey.geometry(
            camera,
            overlap=body.get("overlap"),
            sidelap=body.get("sidelap"),
            height_m=body.get("height_m"),
            gsd_cm=body.get("gsd_cm"),
        )
        area = planning.coverage(
            body.get("vertices"),
            geometry.photo_spacing_m,
            line_spacing=geometry.line_spacing_m,
            max_waypoints=settings.MISSIONS_MAX_WAYPOINTS,
        )
        estimates = _estimates(organisation, body, area.waypoints, geometry.height_m)
    except planning.PlanningError as exc:
        raise Refused(exc.field, exc.message) from None
    return Response(
        {
            "camera": camera.to_dict(),
            "geometry": geometry.to_dict(),
            "coverage": area.to_dict(),
            "line_spacing": round(geometry.line_spacing_m, 3),
            **estimates,
        }
    )


def _estimates(organisation: Organisation, body: dict, waypoints: list, height: float) -> dict:
    """The whole survey for one drone, and each chosen drone's share when it is split."""
    speed = body.get("speed_m_s", settings.MISSIONS_SURVEY_SPEED_M_S)
    drones = _drones(organisation, body.get("drones") or [])
    reserve = organisation_envelope(organisation).battery_reserve
    home = _home(body, drones, waypoints)
    total = survey.estimate(waypoints, home=home, height_m=height, speed_m_s=speed)
    shares = []
    if drones:
        homes = [home_of(d) or home for d in drones]
        for part in planning.split(waypoints, homes):
            drone = drones[part.drone]
            share = survey.estimate(
                [waypoints[i] for i in part.waypoint_indexes],
                home=homes[part.drone],
                height_m=height,
                speed_m_s=speed,
                endurance_s=_endurance_s(drone),
            )
            shares.append(
                {"drone": drone.drone_id, **share.to_dict(), **_margin(drone, share, reserve)}
            )
    return {"total": total.to_dict(), "drones": shares, "battery_reserve_pct": reserve}


def _drones(organisation: Organisation, ids: Any) -> list[Drone]:
    if not isinstance(ids, list) or not all(isinstance(i, str) for i in ids):
        raise planning.PlanningError("drones", "must be a list of drone ids")
    found = {
        d.drone_id: d for d in Drone.objects.filter(organisation=organisation, drone_id__in=ids)
    }
    missing = [i for i in ids if i not in found]
    if missing:
        raise planning.PlanningError("drones", f"no drone {missing[0]!r} in this organisation")
    return [found[i] for i in ids]


def _home(body: dict, drones: list[Drone], waypoints: list) -> list[float]:
    if body.get("home") is not None:
        return list(planning.parse_point(body["home"], "home"))
    placed = next((home_of(d) for d in drones if home_of(d)), None)
    return list(placed) if placed else list(waypoints[0])


def _endurance_s(drone: Drone) -> float:
    """Flight time on a full battery: the gear's ENDURANCE_MIN, else the default."""
    minutes = (drone.specs or {}).get("ENDURANCE_MIN", settings.MISSIONS_SURVEY_ENDURANCE_MIN)
    if isinstance(minutes, bool) or not isinstance(minutes, int | float) or minutes <= 0:
        minutes = settings.MISSIONS_SURVEY_ENDURANCE_MIN
    return float(minutes) * 60.0


def _margin(drone: Drone, share: survey.Estimate, reserve: float) -> dict:
    """What the battery would show at the end, against the envelope's reserve."""
    if drone.battery_remaining is None or share.battery_pct is None:
        return {"battery_now_pct": None, "battery_at_end_pct": None, "enough": None}
    now = drone.battery_remaining * 100.0
    end = now - share.battery_pct
    return {
        "battery_now_pct": round(now, 1),
        "battery_at_end_pct": round(end, 1),
        "enough": end >= reserve,
    }
