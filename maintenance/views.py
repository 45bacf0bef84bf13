"""Maintenance pages: the fleet's due list (with the schedules and bulletins, and an admin's
forms to add them) and a drone's maintenance page (its items, the sign-off form for
admins, its log). Each page acts for the request's current organisation; what a form
sends goes through the same rules as the API."""

from __future__ import annotations

from django.contrib.auth.decorators import login_required
from django.core.exceptions import PermissionDenied
from django.http import HttpRequest, HttpResponse
from django.shortcuts import get_object_or_404, redirect, render
from django.views.decorators.http import require_http_methods

from fleet.lookups import acting_organisation_or_404
from fleet.models import Drone, Organisation, Role
from fleet.permissions import require_role

from . import due, schedules, signoff
from .errors import Refused
from .models import Bulletin, LogEntry, Schedule

LOG_SHOWN = 100


def _number(value: str, field: str) -> float | None:
    """A form's number; empty is none given."""
    if not value.strip():
        return None
    try:
        return float(value)
    except ValueError:
        raise Refused(field, "must be a number") from None


def _form_body(request: HttpRequest) -> tuple[str, dict]:
    """The admin's form as the API's body: a new schedule or a bulletin (or finding)."""
    post = request.POST
    action = post.get("action", "")
    target = {"drone": post.get("drone") or None, "model": post.get("model", "")}
    if action == "schedule":
        triggers = {field: _number(post.get(field, ""), field) for field in schedules.TRIGGERS}
        body = {"name": post.get("name", ""), "notes": post.get("notes", "")}
        return action, {**body, **target, **triggers}
    if action == "bulletin":
        return action, {"title": post.get("title", ""), "text": post.get("text", ""), **target}
    raise Refused("action", "add a schedule or issue a bulletin")


def _apply_form(request: HttpRequest, organisation: Organisation) -> None:
    if not require_role(request.user, organisation, Role.ADMIN):
        raise PermissionDenied("Only organisation admins change maintenance.")
    action, body = _form_body(request)
    if action == "schedule":
        schedules.create(organisation, body, request.user)
    else:
        schedules.issue_bulletin(organisation, body, request.user)


@login_required
@require_http_methods(["GET", "POST"])
def fleet_due(request: HttpRequest) -> HttpResponse:
    """The due list, the schedules and the bulletins; an admin's forms add to them."""
    organisation = acting_organisation_or_404(request)
    error = None
    if request.method == "POST":
        try:
            _apply_form(request, organisation)
            return redirect("maintenance:due")
        except Refused as exc:
            error = f"{exc.field}: {exc.message}"
    return render(
        request,
        "maintenance/due.html",
        {
            "owing": due.fleet_due(organisation),
            "schedules": Schedule.objects.filter(organisation=organisation).select_related("drone"),
            "bulletins": Bulletin.objects.filter(organisation=organisation).select_related("drone"),
            "drones": Drone.objects.filter(organisation=organisation).order_by("drone_id"),
            "can_write": require_role(request.user, organisation, Role.ADMIN),
            "error": error,
        },
        status=400 if error else 200,
    )


def _sign_off_body(request: HttpRequest) -> dict:
    """The form's fields as the API's body: `item` is `schedule:<id>` or `bulletin:<id>`."""
    kind, _, ident = request.POST.get("item", "").partition(":")
    if kind not in ("schedule", "bulletin") or not ident.isdigit():
        raise Refused("schedule", "choose the task to sign off")
    lines = request.POST.get("parts", "").splitlines()
    return {
        kind: int(ident),
        "notes": request.POST.get("notes", ""),
        "parts": [line.strip() for line in lines if line.strip()],
    }


@login_required
@require_http_methods(["GET", "POST"])
def drone_page(request: HttpRequest, drone_id: str) -> HttpResponse:
    organisation = acting_organisation_or_404(request)
    drone = get_object_or_404(Drone, organisation=organisation, drone_id=drone_id)
    error = None
    if request.method == "POST":
        try:
            signoff.sign_off(drone, _sign_off_body(request), request.user)
            return redirect("maintenance:drone", drone_id=drone.drone_id)
        except Refused as exc:
            if exc.status == 403:
                raise PermissionDenied(exc.message) from None
            error = f"{exc.field}: {exc.message}"
    return render(
        request,
        "maintenance/drone.html",
        {
            "drone": drone,
            "items": due.items(drone),
            "log": LogEntry.objects.filter(drone=drone)[:LOG_SHOWN],
            "can_sign": signoff.may_sign_off(request.user, drone),
            "error": error,
        },
        status=400 if error else 200,
    )
