"""`{% battery_card drone %}`: the drone page's battery card (the pack it carries and,
for a flight controller that names none, the choice of one)."""

from __future__ import annotations

from django import template

from fleet.models import Drone

from .. import fitting
from ..models import Battery

register = template.Library()


@register.inclusion_tag("batteries/_drone_card.html", takes_context=True)
def battery_card(context: template.Context, drone: Drone) -> dict:
    membership = context.get("current_membership")
    return {
        "drone": drone,
        "carried": fitting.carried(drone),
        "reported_serial": fitting.reported_serial(drone),
        "choices": Battery.objects.filter(organisation_id=drone.organisation_id, reported=False),
        "can_operate": bool(membership and membership.allows("operator")),
        "csrf_token": context.get("csrf_token"),
    }
