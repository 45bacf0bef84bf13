"""Portal pages: mission list and detail (live), the Mission Planner, the mission-log
viewer, the panic button, and the pictures behind the organisation check."""

from __future__ import annotations

import uuid

from django.conf import settings
from django.contrib.auth.decorators import login_required
from django.http import FileResponse, Http404, HttpRequest, HttpResponse
from django.shortcuts import get_object_or_404, render
from django.urls import reverse

from fleet import envelopes
from fleet.models import Role
from fleet.permissions import require_role
from fleet.tenancy import acting_organisation
from onboard.protocol import STEP_COMMANDS

from .models import Mission, MissionStatus, Picture

# Stands for a mission id in URLs handed to the page's script.
UUID_PLACEHOLDER = "00000000-0000-0000-0000-000000000000"


def _organisation(request: HttpRequest):  # type: ignore[no-untyped-def]
    organisation = acting_organisation(request)
    if organisation is None:
        raise Http404("You are not a member of any organisation.")
    return organisation


def _map_config(organisation, **extra: object) -> dict:  # type: ignore[no-untyped-def]
    """Tiles and a starting view for the page's map (a drone of the organisation, if any)."""
    placed = organisation.drones.filter(lat__isnull=False).order_by("-online", "drone_id").first()
    center = [placed.lat, placed.lon] if placed else [40.6303, -8.6575]
    return {
        "tileUrl": getattr(settings, "MAP_TILE_URL", ""),
        "attribution": getattr(settings, "MAP_TILE_ATTRIBUTION", ""),
        "center": center,
        **extra,
    }


@login_required
def mission_list(request: HttpRequest) -> HttpResponse:
    missions = Mission.objects.filter(organisation=_organisation(request))
    status = request.GET.get("status", "")
    if status in MissionStatus.values:
        missions = missions.filter(status=status)
    query = request.GET.get("q", "").strip()
    if query:
        missions = missions.filter(name__icontains=query)
    drone = request.GET.get("drone", "").strip()
    if drone:
        missions = missions.filter(assignments__drone__drone_id=drone).distinct()
    return render(
        request,
        "missions/list.html",
        {
            "missions": missions[:200],
            "statuses": MissionStatus.choices,
            "status": status,
            "q": query,
            "drone": drone,
        },
    )


@login_required
def mission_detail(request: HttpRequest, pk: str) -> HttpResponse:
    mission = get_object_or_404(Mission, pk=pk, organisation=_organisation(request))
    return render(
        request,
        "missions/detail.html",
        {
            "mission": mission,
            "steps": mission.steps.select_related("drone"),
            "assignments": mission.assignments.select_related("drone"),
            "events": mission.events.select_related("drone")[:500],
            "pictures": mission.pictures.all()[:500],
            "can_operate": require_role(request.user, mission.organisation, Role.OPERATOR),
            "mission_config": _map_config(
                mission.organisation,
                missionId=str(mission.pk),
                missionApi=reverse("api:mission-detail", args=[mission.pk]),
                logApi=reverse("api:mission-log", args=[mission.pk]),
                socket=f"/ws/missions/{mission.pk}/",
                fence=envelopes.envelope_body(mission.organisation).get("geoFence"),
                reserve=settings.MISSIONS_BATTERY_RESERVE,
            ),
        },
    )


@login_required
def planner(request: HttpRequest) -> HttpResponse:
    organisation = _organisation(request)
    return render(
        request,
        "missions/planner.html",
        {
            "drones": organisation.drones.all(),
            "commands": STEP_COMMANDS,
            "planner_config": _map_config(
                organisation,
                coverageUrl=reverse("api:mission-coverage"),
                surveyUrl=reverse("api:mission-survey"),
                camerasUrl=reverse("api:mission-survey-cameras"),
                dronesUrl=reverse("api:drone-list"),
                createUrl=reverse("api:mission-list"),
                checkUrl=reverse("api:mission-check-envelope"),
                envelopeUrl=reverse("api:organisation-envelope", args=[organisation.slug]),
                reservationsUrl=reverse("api:organisation-reservations", args=[organisation.slug]),
                startUrl=reverse("api:mission-start", args=[UUID_PLACEHOLDER]),
                missionUrl=reverse("missions:detail", args=[UUID_PLACEHOLDER]),
                placeholder=UUID_PLACEHOLDER,
            ),
        },
    )


def _mission_id(value: str) -> uuid.UUID:
    """A mission id from a query parameter; anything that is not one is an unknown
    mission (404), not a server error."""
    try:
        return uuid.UUID(value)
    except ValueError:
        raise Http404("No such mission.") from None


@login_required
def log_viewer(request: HttpRequest) -> HttpResponse:
    organisation = _organisation(request)
    mission = None
    if request.GET.get("mission"):
        mission = Mission.objects.filter(
            organisation=organisation, pk=_mission_id(request.GET["mission"])
        ).first()
    return render(
        request,
        "missions/log_viewer.html",
        {
            "mission": mission,
            "missions": Mission.objects.filter(organisation=organisation)[:50],
            "viewer_config": _map_config(
                organisation,
                checkUrl=reverse("api:mission-check-log"),
                logUrl=reverse("api:mission-log", args=[UUID_PLACEHOLDER]),
                videoUrl=reverse("api:mission-video", args=[UUID_PLACEHOLDER]),
                placeholder=UUID_PLACEHOLDER,
                mission=str(mission.pk) if mission else None,
            ),
        },
    )


@login_required
def panic_page(request: HttpRequest) -> HttpResponse:
    organisation = _organisation(request)
    return render(
        request,
        "missions/panic.html",
        {
            "panic_config": {
                "panicUrl": reverse("api:mission-panic"),
                "missionApi": reverse("api:mission-detail", args=[UUID_PLACEHOLDER]),
                "droneApi": reverse("api:drone-detail", args=["__DRONE__"]),
                "placeholder": UUID_PLACEHOLDER,
                "organisation": organisation.slug,
            }
        },
    )


def _picture(request: HttpRequest, pk: int) -> Picture:
    return get_object_or_404(Picture, pk=pk, mission__organisation=_organisation(request))


@login_required
def picture(request: HttpRequest, pk: int) -> FileResponse:
    row = _picture(request, pk)
    return FileResponse(row.image.open("rb"), content_type="image/jpeg", filename=row.name)


@login_required
def picture_thumbnail(request: HttpRequest, pk: int) -> FileResponse:
    row = _picture(request, pk)
    return FileResponse(row.thumbnail.open("rb"), content_type="image/jpeg")
