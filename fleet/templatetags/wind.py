"""The drone page's wind card: the flight controller's estimate against the drone's limit."""

from __future__ import annotations

from django import template

from fleet import wind
from fleet.models import Drone

register = template.Library()


@register.inclusion_tag("fleet/wind_card.html")
def wind_card(drone: Drone) -> dict:
    return {"wind": wind.view(drone)}
