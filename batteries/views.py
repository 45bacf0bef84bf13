"""Portal pages: the organisation's batteries with their health and cycles (naming a new
pack), and the drone page's choice of the pack a drone carries. Plain forms, no script."""

from __future__ import annotations

from django.contrib import messages
from django.contrib.auth.decorators import login_required
from django.http import Http404, HttpRequest, HttpResponse
from django.shortcuts import get_object_or_404, redirect, render
from django.views.decorators.http import require_POST

from fleet.models import Drone, Organisation
from fleet.tenancy import acting_membership

from . import fitting, policy, usage
from .fitting import BatteryRefused
from .models import Battery


def _organisation_or_404(request: HttpRequest) -> Organisation:
    membership = acting_membership(request)
    if membership is None:
        raise Http404("You are not a member of any organisation.")
    return membership.organisation


def _may(request: HttpRequest, role: str) -> bool:
    membership = acting_membership(request)
    return bool(membership and membership.allows(role))


def _may_operate(request: HttpRequest) -> bool:
    return _may(request, "operator")


@login_required
def battery_list(request: HttpRequest) -> HttpResponse:
    organisation = _organisation_or_404(request)
    if request.method == "POST":
        return _name_battery(request, organisation)
    fitting.sync(Drone.objects.filter(organisation=organisation, fc__has_key="battery_serial"))
    packs = Battery.objects.filter(organisation=organisation).select_related("drone")
    return render(
        request,
        "batteries/list.html",
        {
            "batteries": packs,
            "rules": usage.policy_of(organisation.pk),
            "can_operate": _may_operate(request),
            "can_set_rules": _may(request, "admin"),
        },
    )


def _name_battery(request: HttpRequest, organisation: Organisation) -> HttpResponse:
    if not _may_operate(request):
        raise Http404("Only operators and admins name batteries.")
    rated = request.POST.get("rated_energy_wh", "").strip()
    data: dict = {"serial": request.POST.get("serial", "")}
    try:
        if rated:
            data["rated_energy_wh"] = float(rated)
        battery = policy.new_battery(organisation, data, request.user)
    except ValueError:
        messages.error(request, "rated_energy_wh: must be a number")
    except BatteryRefused as exc:
        messages.error(request, f"{exc.field}: {exc.message}")
    else:
        messages.success(request, f"Battery {battery.serial} added.")
    return redirect("batteries:list")


@login_required
@require_POST
def choose(request: HttpRequest, drone_id: str) -> HttpResponse:
    """The drone page's form: the pack this drone carries (operators)."""
    organisation = _organisation_or_404(request)
    drone = get_object_or_404(Drone, organisation=organisation, drone_id=drone_id)
    if not _may_operate(request):
        raise Http404("Only operators and admins choose batteries.")
    try:
        chosen = fitting.choose(drone, request.POST.get("battery") or None, request.user)
    except BatteryRefused as exc:
        messages.error(request, f"{exc.field}: {exc.message}")
    else:
        messages.success(request, f"{drone.drone_id} carries {chosen or 'no battery'}.")
    return redirect("fleet:drone", drone_id=drone.drone_id)


@login_required
@require_POST
def rules(request: HttpRequest) -> HttpResponse:
    """The batteries page's form: the organisation's retirement rules (admins)."""
    organisation = _organisation_or_404(request)
    if not _may(request, "admin"):
        raise Http404("Only admins set battery rules.")
    try:
        data = {
            "health_threshold": _form_number(request, "health_threshold"),
            "cycle_limit": _form_number(request, "cycle_limit"),
        }
        policy.set_policy(organisation, data, request.user)
    except BatteryRefused as exc:
        messages.error(request, f"{exc.field}: {exc.message}")
    else:
        messages.success(request, "Battery rules saved; every pack judged again.")
    return redirect("batteries:list")


def _form_number(request: HttpRequest, name: str) -> float | None:
    """A number from the form (None when left empty); BatteryRefused names the field."""
    text = request.POST.get(name, "").strip()
    if not text:
        return None
    try:
        return float(text)
    except ValueError:
        raise BatteryRefused(name, "must be a number") from None
