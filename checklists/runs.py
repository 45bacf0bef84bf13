"""Running a checklist for a drone: the person's answers and the automatic values, kept
together as one append-only run (models.Run); the audit trail gets an entry for it
(accounts/receivers.py hears the new row), and the flight record that follows names it
(`flight_event`, read by records/building.py)."""

from __future__ import annotations

from datetime import datetime, timedelta
from typing import Any

from django.utils import timezone

from fleet.models import Drone

from . import checks
from .items import MANUAL, ChecklistError, clean_answers
from .models import Run, Template


def _template(drone: Drone, template_id: Any) -> Template:
    if isinstance(template_id, bool) or not isinstance(template_id, int):
        raise ChecklistError("template", "must be a template id")
    template = Template.objects.filter(
        pk=template_id, organisation_id=drone.organisation_id, active=True
    ).first()
    if template is None:
        raise ChecklistError("template", f"no active template {template_id} in this organisation")
    return template


def _results(drone: Drone, items: list[dict], answers: list[bool]) -> list[dict]:
    given = iter(answers)
    out = []
    for item in items:
        if item["kind"] == MANUAL:
            out.append({"kind": MANUAL, "text": item["text"], "passed": next(given)})
        else:
            out.append(checks.measure(drone, item).to_dict())
    return out


def _failures(results: list[dict]) -> list[str]:
    found = []
    for result in results:
        if result["passed"]:
            continue
        if result["kind"] == MANUAL:
            found.append(f"not confirmed: {result['text']}")
        else:
            found.append(f"{result['label']}: {result['why']}")
    return found


def run_checklist(drone: Drone, data: Any, user: Any) -> Run:
    """Measure the template's automatic items now, take the answers and keep the run.

    `data`: `{"template": id, "answers": [true/false per manual item]}`. Bad input raises
    ChecklistError and stores nothing; a failed run is stored (it is a fact too)."""
    if not isinstance(data, dict):
        raise ChecklistError("body", "must be a JSON object")
    unknown = sorted(set(data) - {"template", "answers"})
    if unknown:
        raise ChecklistError(unknown[0], "unknown field")
    template = _template(drone, data.get("template"))
    answers = clean_answers(template.items, data.get("answers"))
    results = _results(drone, template.items, answers)
    failures = _failures(results)
    at = timezone.now()
    return Run.objects.create(
        organisation_id=drone.organisation_id,
        drone=drone,
        template=template,
        template_name=template.name,
        results=results,
        passed=not failures,
        failures=failures,
        run_by=user if getattr(user, "pk", None) else None,
        run_by_name=user.get_username() if getattr(user, "pk", None) else "",
        at=at,
        expires_at=at + timedelta(minutes=template.valid_minutes),
    )


def run_dict(run: Run) -> dict:
    return {
        "id": run.pk,
        "drone": run.drone.drone_id,
        "template": run.template_id,
        "template_name": run.template_name,
        "passed": run.passed,
        "failures": list(run.failures),
        "results": run.results,
        "run_by": run.run_by_name,
        "at": run.at.isoformat(),
        "expires_at": run.expires_at.isoformat(),
    }


def flight_event(drone: Drone, armed_at: datetime) -> dict | None:
    """The passed run a flight armed at `armed_at` flew on, as a flight record's event."""
    run = (
        Run.objects.filter(drone=drone, passed=True, at__lte=armed_at, expires_at__gt=armed_at)
        .order_by("-at", "-id")
        .first()
    )
    if run is None:
        return None
    return {
        "at": run.at.isoformat(),
        "kind": "checklist",
        "level": "info",
        "message": f"Checklist {run.template_name!r} passed, run by {run.run_by_name or 'the platform'}.",
        "source": f"checklist:{run.pk}",
        "checklist": run_dict(run),
    }
