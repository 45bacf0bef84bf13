"""Whether a drone may fly: the organisation's rule, the drone's newest passed checklist,
and the automatic items the platform runs before its own work picks a drone.

- A manual arm (or a take-off that arms) and a mission started by a person need, for the
  drone, a passed checklist run whose validity has not ended (`refusal`; 409
  `checklist_required`).
- Replacement, collaboration, panic and the nearest-available choice run the automatic
  items of the organisation's active templates (`automatic_failures`) and skip a drone
  that fails one.

Both apply only where the organisation requires checklists (its `Policy`, else the site's
CHECKLIST_REQUIRED_DEFAULT).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from datetime import datetime

from django.conf import settings
from django.db.models import Exists, OuterRef, Subquery, Value
from django.db.models.functions import Coalesce
from django.utils import timezone

from fleet.models import Drone, Organisation

from . import checks
from .models import Policy, Run, Template


@dataclass(frozen=True)
class Rule:
    required: bool
    valid_minutes: int

    def to_dict(self) -> dict:
        return {"required": self.required, "valid_minutes": self.valid_minutes}


def rule_of(organisation: Organisation) -> Rule:
    """The organisation's own rule, else the site's defaults."""
    policy = Policy.objects.filter(organisation=organisation).first()
    if policy is None:
        return Rule(settings.CHECKLIST_REQUIRED_DEFAULT, settings.CHECKLIST_VALID_MINUTES_DEFAULT)
    return Rule(policy.required, policy.valid_minutes)


def current_run(drone: Drone, at: datetime | None = None) -> Run | None:
    """The drone's newest passed run still valid at `at` (now), if any."""
    at = at or timezone.now()
    return (
        Run.objects.filter(drone=drone, passed=True, at__lte=at, expires_at__gt=at)
        .order_by("-at", "-id")
        .first()
    )


def state_of(drone: Drone) -> dict:
    """What the fleet page shows: required or not, and the newest run's outcome and expiry."""
    last = Run.objects.filter(drone=drone).order_by("-at", "-id").first()
    return _state(rule_of(drone.organisation), last, timezone.now())


def states_for(drones: Iterable[Drone]) -> dict[int, dict]:
    """`state_of` for many drones (of one or more organisations) in two queries."""
    drones = list(drones)
    rules: dict[int, Rule] = {}
    for drone in drones:
        if drone.organisation_id not in rules:
            rules[drone.organisation_id] = rule_of(drone.organisation)
    newest = (
        Run.objects.filter(drone__in=drones).order_by("drone_id", "-at", "-id").distinct("drone_id")
    )
    last = {run.drone_id: run for run in newest}
    now = timezone.now()
    return {d.pk: _state(rules[d.organisation_id], last.get(d.pk), now) for d in drones}


def _state(rule: Rule, last: Run | None, now: datetime) -> dict:
    if last is None:
        status = "none"
    elif not last.passed:
        status = "failed"
    else:
        status = "passed" if last.expires_at > now else "expired"
    return {
        "required": rule.required,
        "status": status,
        "run": None if last is None else last.pk,
        "at": None if last is None else last.at.isoformat(),
        "expires_at": None if last is None or not last.passed else last.expires_at.isoformat(),
        "failures": [] if last is None else list(last.failures),
    }


# The annotations a drone looked up with `lookup_reads` carries: whether its
# organisation requires a checklist (its Policy, else the site's default), and whether it
# has a passed run still valid when it was looked up.
REQUIRED, VALID_RUN = "checklist_required", "checklist_valid_run"


def lookup_reads(at: datetime | None = None) -> dict:
    """The gate's reads, as at `at` (now), as annotations of a query of drones (the one
    that finds the drone a command is for): `refusal` then answers a drone that may fly
    without a query."""
    now = at or timezone.now()
    policy = Policy.objects.filter(organisation=OuterRef("organisation_id")).values("required")
    return {
        REQUIRED: Coalesce(Subquery(policy[:1]), Value(settings.CHECKLIST_REQUIRED_DEFAULT)),
        VALID_RUN: Exists(
            Run.objects.filter(drone=OuterRef("pk"), passed=True, at__lte=now, expires_at__gt=now)
        ),
    }


def _clear_from_lookup(drone: Drone) -> bool:
    """The drone's lookup already says it may fly (not required, or a valid run)."""
    return getattr(drone, REQUIRED, True) is False or getattr(drone, VALID_RUN, False) is True


def refusal(drone: Drone) -> str | None:
    """Why a person may not fly this drone yet (None: a valid passed run, or not required)."""
    if _clear_from_lookup(drone):
        return None
    if not rule_of(drone.organisation).required or current_run(drone) is not None:
        return None
    last = Run.objects.filter(drone=drone).order_by("-at", "-id").first()
    if last is None:
        why = "no checklist has been run"
    elif not last.passed:
        why = "its last checklist failed"
    else:
        why = "its last passed checklist has expired"
    return f"Drone {drone.drone_id} needs a passed pre-flight checklist: {why}."


def automatic_items(organisation: Organisation) -> list[dict]:
    """Every automatic item of the organisation's active templates, each once (the
    strictest threshold where several templates measure the same thing)."""
    strictest: dict[str, dict] = {}
    for template in Template.objects.filter(organisation=organisation, active=True):
        for item in template.items:
            if item["kind"] != "auto":
                continue
            seen = strictest.get(item["check"])
            if seen is None or _stricter(item, seen):
                strictest[item["check"]] = item
    return list(strictest.values())


def _stricter(item: dict, than: dict) -> bool:
    if item["threshold"] is None or than["threshold"] is None:
        return False
    # For `link` a lower threshold (a fresher heartbeat) is stricter; for the others, higher.
    if item["check"] == "link":
        return item["threshold"] < than["threshold"]
    return item["threshold"] > than["threshold"]


def automatic_items_for(organisation_id: int) -> list[dict]:
    """The automatic items the platform's own work holds the organisation's drones to:
    none where checklists are not required."""
    organisation = Organisation.objects.get(pk=organisation_id)
    if not rule_of(organisation).required:
        return []
    return automatic_items(organisation)


def failing(drone: Drone, items: list[dict], cache: dict | None = None) -> list[str]:
    """Why the platform's own work may not pick the drone (empty: it may); `cache` is
    shared by the drones of one choice (checks.measure)."""
    return checks.automatic_failures(drone, items, cache) if items else []
