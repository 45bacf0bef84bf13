"""The portal page of the acting organisation's checklists: its templates and its rule
for every member; admins create and retire templates and set the rule through plain
forms (no script). Refusals name the field, as the API's do, and change nothing."""

from __future__ import annotations

from django.contrib import messages
from django.contrib.auth.decorators import login_required
from django.core.exceptions import PermissionDenied
from django.http import Http404, HttpRequest, HttpResponse, QueryDict
from django.shortcuts import redirect, render

from fleet.models import Membership, Role
from fleet.tenancy import acting_membership

from . import definitions, gate
from .items import CHECKS, ChecklistError
from .models import Template


def _number(text: str) -> int | float | str:
    """A form's number as JSON would carry it; anything else is kept for the refusal."""
    try:
        value = float(text)
    except ValueError:
        return text
    return int(value) if value.is_integer() else value


def template_body(form: QueryDict) -> dict:
    """The API's template body from the form: manual items one per line, then each
    automatic item ticked, with its threshold where it has one."""
    lines = [line.strip() for line in form.get("manual", "").splitlines() if line.strip()]
    items: list[dict] = [{"kind": "manual", "text": line} for line in lines]
    for name, check in CHECKS.items():
        if not form.get(f"auto_{name}"):
            continue
        item = {"kind": "auto", "check": name}
        if check.has_threshold:
            item["threshold"] = _number(form.get(f"threshold_{name}", ""))
        items.append(item)
    return {
        "name": form.get("name", ""),
        "items": items,
        "valid_minutes": _number(form.get("valid_minutes", "")),
    }


def _admin(membership: Membership) -> None:
    if not membership.allows(Role.ADMIN):
        raise PermissionDenied("Only admins define checklists.")


def _post(request: HttpRequest, membership: Membership) -> None:
    _admin(membership)
    organisation, action = membership.organisation, request.POST.get("action")
    if action == "create":
        definitions.create_template(organisation, template_body(request.POST), request.user)
        messages.info(request, "Checklist created.")
    elif action == "retire":
        found = Template.objects.filter(
            organisation=organisation, pk=request.POST.get("template") or 0, active=True
        ).first()
        if found is None:
            raise Http404("No such checklist template.")
        definitions.retire_template(found, request.user)
        messages.info(request, f"Checklist {found.name!r} retired.")
    elif action == "rule":
        body = {
            "required": bool(request.POST.get("required")),
            "valid_minutes": _number(request.POST.get("valid_minutes", "")),
        }
        definitions.set_rule(organisation, body, request.user)
        messages.info(request, "Checklist rule saved.")
    else:
        raise Http404("No such action.")


@login_required
def templates_page(request: HttpRequest) -> HttpResponse:
    membership = acting_membership(request)
    if membership is None:
        raise Http404("You are not a member of any organisation.")
    if request.method == "POST":
        try:
            _post(request, membership)
        except ChecklistError as exc:
            messages.error(request, f"Not saved: {exc}")
        return redirect("checklists:templates")
    organisation = membership.organisation
    return render(
        request,
        "checklists/templates.html",
        {
            "templates": Template.objects.filter(organisation=organisation, active=True),
            "rule": gate.rule_of(organisation),
            "checks": [(name, check) for name, check in CHECKS.items()],
            "is_admin": membership.allows(Role.ADMIN),
        },
    )
