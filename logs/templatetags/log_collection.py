"""`{% log_collection_card drone %}`: the drone page's card of when the drone uploads its
logs after landing (logs/policy.py), with the form operators and admins change it by."""

from __future__ import annotations

from django import template

from fleet.models import Drone, LogCollection, Role

register = template.Library()


@register.inclusion_tag("logs/_collection_card.html", takes_context=True)
def log_collection_card(context: template.Context, drone: Drone) -> dict:
    membership = context.get("current_membership")
    return {
        "drone": drone,
        "modes": LogCollection.choices,
        "label": LogCollection(drone.log_collection).label,
        "can_operate": bool(membership and membership.allows(Role.OPERATOR)),
        "csrf_token": context.get("csrf_token"),
    }
