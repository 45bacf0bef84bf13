"""The drone page's log collection form (`POST /logs/collection/{drone_id}/`): operators
and admins of the acting organisation set the mode; a viewer is refused (403), another
organisation's drone is not found (404), a bad value answers 400 naming the field."""

from __future__ import annotations

from django.contrib import messages
from django.contrib.auth.decorators import login_required
from django.core.exceptions import PermissionDenied
from django.http import Http404, HttpRequest, HttpResponse, HttpResponseBadRequest
from django.shortcuts import get_object_or_404, redirect
from django.views.decorators.http import require_POST

from fleet.models import Drone, LogCollection, Role
from fleet.tenancy import acting_membership
from logs import policy


@login_required
@require_POST
def set_collection(request: HttpRequest, drone_id: str) -> HttpResponse:
    membership = acting_membership(request)
    if membership is None:
        raise Http404("You are not a member of any organisation.")
    drone = get_object_or_404(
        Drone.objects.select_related("organisation"),
        organisation=membership.organisation,
        drone_id=drone_id,
    )
    if not membership.allows(Role.OPERATOR):
        raise PermissionDenied("Only operators and admins set log collection.")
    data = {policy.FIELD: request.POST.get(policy.FIELD, "")}
    try:
        policy.set_drone_policy(drone, data, request.user)
    except policy.PolicyError as exc:
        return HttpResponseBadRequest(f"{exc.field}: {exc.message}", content_type="text/plain")
    label = LogCollection(drone.log_collection).label.lower()
    messages.success(request, f"{drone.drone_id}: log collection {label}.")
    return redirect("fleet:drone", drone_id=drone.drone_id)
