"""What a mission may hold, and creating one as a draft (nothing is sent until it starts)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from django.db import transaction
from django.utils import timezone

from fleet import envelopes
from fleet.models import Organisation
from missions.errors import MissionError, outside_envelope
from missions.models import (
    Mission,
    Step,
)
from onboard import protocol

MAX_STEPS = 100_000


def validate_steps(raw_steps: Any) -> list[dict]:
    """Steps as the API receives them → mission steps, indexes 0..n-1 in list order.

    An `index` given by the client must equal its position (the mission's index space is
    dense); commands and params are checked with the drone's own rules.
    """
    if not isinstance(raw_steps, list):
        raise MissionError("steps", "must be a list of steps")
    if not raw_steps:
        raise MissionError("steps", "a mission needs at least one step")
    if len(raw_steps) > MAX_STEPS:
        raise MissionError("steps", f"at most {MAX_STEPS} steps")
    steps = []
    for position, raw in enumerate(raw_steps):
        if isinstance(raw, Mapping) and "index" not in raw:
            raw = {**raw, "index": position}
        try:
            step = protocol.parse_step(raw, f"steps[{position}]")
        except protocol.ProtocolError as exc:
            raise MissionError(exc.field, exc.message) from None
        if step.index != position:
            raise MissionError(
                f"steps[{position}].index", f"must be {position} (steps are numbered in order)"
            )
        steps.append(step.to_dict())
    return steps


def create_mission(
    *,
    organisation: Organisation,
    name: str,
    steps: Any,
    altitude: float = 10.0,
    extensibility: Mapping | None = None,
    user: Any = None,
    home: Sequence[float] | None = None,
    fence: Mapping | None = None,
    confirmed: bool = False,
) -> Mission:
    """A draft mission with validated steps (nothing is sent until `start_mission`).

    The steps must keep to the organisation's envelope, and to `fence` (an imported
    plan's own geoFence), flown from `home` (a plan's home; else fleet.envelopes.plan_home);
    steps beyond the envelope's defaults need `confirmed`.
    """
    clean = validate_steps(steps)
    try:
        envelopes.check_plan(organisation, clean, home, fence)
        if not confirmed:
            envelopes.confirm_steps(organisation, clean, home=home)
    except envelopes.EnvelopeRefusal as exc:
        raise outside_envelope(exc) from None
    name = (name or "").strip() or f"Mission {timezone.now():%Y-%m-%d %H:%M}"
    with transaction.atomic():
        mission = Mission.objects.create(
            organisation=organisation,
            name=name[:200],
            altitude=altitude,
            extensibility=dict(extensibility) if extensibility else None,
            created_by=user if getattr(user, "is_authenticated", False) else None,
            fence=dict(fence)
            if fence and (fence.get("polygons") or fence.get("circles"))
            else None,
            plan_home=list(home) if home is not None else None,
        )
        Step.objects.bulk_create(
            Step(mission=mission, index=s["index"], command=s["command"], params=s["params"])
            for s in clean
        )
    return mission
