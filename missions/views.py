from __future__ import annotations

from django.contrib.auth.decorators import login_required
from django.http import Http404, HttpRequest, HttpResponse
from django.shortcuts import get_object_or_404, render

from .models import Mission, MissionStatus


@login_required
def mission_list(request: HttpRequest) -> HttpResponse:
    organisation = request.organisation  # type: ignore[attr-defined]
    if organisation is None:
        raise Http404("You are not a member of any organisation.")
    missions = Mission.objects.filter(organisation=organisation)
    status = request.GET.get("status", "")
    if status in MissionStatus.values:
        missions = missions.filter(status=status)
    query = request.GET.get("q", "").strip()
    if query:
        missions = missions.filter(name__icontains=query)
    return render(
        request,
        "missions/list.html",
        {
            "missions": missions[:200],
            "statuses": MissionStatus.choices,
            "status": status,
            "q": query,
        },
    )


@login_required
def mission_detail(request: HttpRequest, pk: str) -> HttpResponse:
    organisation = request.organisation  # type: ignore[attr-defined]
    mission = get_object_or_404(Mission, pk=pk, organisation=organisation)
    return render(
        request,
        "missions/detail.html",
        {
            "mission": mission,
            "steps": mission.steps.select_related("drone"),
            "assignments": mission.assignments.select_related("drone"),
            "events": mission.events.select_related("drone")[:500],
        },
    )
