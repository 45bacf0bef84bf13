"""The portal page that runs a pre-flight checklist for one drone of the acting
organisation: a plain form per active template (no script), its results, recent runs."""

from __future__ import annotations

from django.contrib import messages
from django.contrib.auth.decorators import login_required
from django.core.exceptions import PermissionDenied
from django.http import Http404, HttpRequest, HttpResponse
from django.shortcuts import get_object_or_404, redirect, render

from fleet import airworthiness
from fleet.models import Drone, Role
from fleet.tenancy import acting_membership

from . import gate, runs
from .items import CHECKS, MANUAL, ChecklistError
from .models import Run, Template

RECENT_RUNS = 10


def _template_rows(template: Template) -> list[dict]:
    """The template's items as the form shows them, manual ones numbered in order."""
    rows, manual = [], 0
    for item in template.items:
        if item["kind"] == MANUAL:
            rows.append({"manual": True, "text": item["text"], "index": manual})
            manual += 1
        else:
            check = CHECKS[item["check"]]
            rows.append(
                {
                    "manual": False,
                    "text": check.label,
                    "threshold": item["threshold"],
                    "unit": check.unit,
                }
            )
    return rows


def _answers(request: HttpRequest, template: Template) -> list[bool]:
    count = sum(1 for item in template.items if item["kind"] == MANUAL)
    ticked = set(request.POST.getlist("confirmed"))
    return [str(i) in ticked for i in range(count)]


@login_required
def drone_checklist(request: HttpRequest, drone_id: str) -> HttpResponse:
    membership = acting_membership(request)
    if membership is None:
        raise Http404("You are not a member of any organisation.")
    drone = get_object_or_404(
        Drone.objects.select_related("organisation"),
        organisation=membership.organisation,
        drone_id=drone_id,
    )
    may_run = membership.allows(Role.OPERATOR)
    templates = list(Template.objects.filter(organisation=drone.organisation, active=True))
    if request.method == "POST":
        if not may_run:
            raise PermissionDenied("Only operators and admins run checklists.")
        template = next((t for t in templates if str(t.pk) == request.POST.get("template")), None)
        if template is None:
            raise Http404("No such checklist template.")
        try:
            run = runs.run_checklist(
                drone,
                {"template": template.pk, "answers": _answers(request, template)},
                request.user,
            )
        except ChecklistError as exc:
            messages.error(request, str(exc))
        else:
            outcome = "passed" if run.passed else "failed"
            messages.info(request, f"Checklist {run.template_name!r} {outcome}.")
        return redirect("checklists:drone", drone_id=drone.drone_id)
    recent = Run.objects.filter(drone=drone)[:RECENT_RUNS]
    return render(
        request,
        "checklists/drone.html",
        {
            "drone": drone,
            "may_run": may_run,
            "templates": [(t, _template_rows(t)) for t in templates],
            "state": gate.state_of(drone),
            "airworthiness": airworthiness.verdict(drone),
            "runs": recent,
        },
    )
