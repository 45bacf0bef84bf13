"""QGroundControl `.plan` files in and out of stored missions (missions.qgc_plan does the
format; this module decides which home, fence and organisation a plan goes with).

Export: plannedHomePosition is the imported plan's own home, else the home of the drone
that last flew the mission, else the organisation's home, else the first waypoint; the
geoFence is the organisation's fence together with the mission's own.

Import: every item goes through the flight envelope as any mission does. The plan's
geoFence becomes the mission's own fence (checked again at start), or, asked for with
`fence="organisation"` by an admin, the organisation's fence (its other limits kept).
Heights above terrain are turned into heights above home with the imported terrain.
Anything refused leaves nothing behind: no mission, no envelope change.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from django.db import transaction

from fleet import envelopes
from fleet.models import Membership, Organisation, Role
from missions.creation import create_mission
from missions.errors import MissionError
from onboard.envelope import EnvelopeError
from terrain import elevation

from . import qgc_plan, wpl
from .models import Assignment, Mission
from .planning import PlanningError

FENCE_SCOPES = ("mission", "organisation")


def _home(mission: Mission) -> list[float] | None:
    if mission.plan_home:
        return list(mission.plan_home)
    last = (
        Assignment.objects.filter(mission=mission).select_related("drone").order_by("-id").first()
    )
    if last is not None:
        home = envelopes.home_of(last.drone)
        if home is not None:
            return [home[0], home[1], 0.0]
    stored = (mission.organisation.envelope or {}).get("home")
    return [stored[0], stored[1], 0.0] if stored else None


def _fence(mission: Mission) -> dict:
    """The organisation's fence and the mission's own, both of which the drone keeps to."""
    organisation = qgc_plan.read_geofence(envelopes.envelope_body(mission.organisation)["geoFence"])
    own = qgc_plan.read_geofence(mission.fence) if mission.fence else {}
    return {
        "polygons": organisation["polygons"] + own.get("polygons", []),
        "circles": organisation["circles"] + own.get("circles", []),
    }


def export_document(mission: Mission) -> dict:
    """The mission as a QGroundControl plan document (QgcPlanError if it has no form)."""
    steps = [
        {"index": s.index, "command": s.command, "params": s.params}
        for s in mission.steps.order_by("index")
    ]
    return qgc_plan.export_plan(
        steps, home=_home(mission), geofence=_fence(mission), altitude=mission.altitude
    )


def _plan_altitude(steps: list[dict]) -> float:
    for step in steps:
        if step.get("command") == "takeoff":
            return float(step["params"].get("altitude") or qgc_plan.DEFAULT_ALTITUDE)
    return qgc_plan.DEFAULT_ALTITUDE


def _set_organisation_fence(organisation: Organisation, user: Any, fence: Mapping) -> None:
    membership = Membership.objects.for_user(user).filter(organisation=organisation).first()
    if membership is None or not membership.allows(Role.ADMIN):
        raise MissionError("fence", "only an admin may replace the organisation's fence", 403)
    body = {**(organisation.envelope or {}), "geoFence": qgc_plan.geofence_json(fence)}
    try:
        envelopes.set_envelope(organisation, body)
    except EnvelopeError as exc:
        raise MissionError(f"geoFence.{exc.field}", exc.message) from None


def import_document(
    source: str | bytes | Mapping,
    *,
    organisation: Organisation,
    user: Any,
    name: str = "",
    fence_scope: str = "mission",
    confirmed: bool = False,
) -> Mission:
    """A draft mission from a plan (a `.plan`, or a QGC WPL text file);
    PlanningError / MissionError say what is wrong."""
    if fence_scope not in FENCE_SCOPES:
        raise MissionError("fence", f"must be one of {', '.join(FENCE_SCOPES)}")
    plan = qgc_plan.import_plan(wpl.plan_document(source), terrain=elevation)
    has_fence = bool(plan.geofence["polygons"] or plan.geofence["circles"])
    with transaction.atomic():
        if has_fence and fence_scope == "organisation":
            _set_organisation_fence(organisation, user, plan.geofence)
        return create_mission(
            organisation=organisation,
            name=name or "Imported plan",
            steps=plan.steps,
            altitude=_plan_altitude(plan.steps),
            user=user,
            home=plan.home,
            fence=qgc_plan.geofence_json(plan.geofence) if fence_scope == "mission" else None,
            confirmed=confirmed,
        )


__all__ = ["FENCE_SCOPES", "PlanningError", "export_document", "import_document"]
