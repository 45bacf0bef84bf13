"""REST: the organisation's recent alerts, newest first; webhook URLs to admins only."""

from __future__ import annotations

from drf_spectacular.utils import extend_schema, inline_serializer
from rest_framework import serializers
from rest_framework.decorators import api_view, permission_classes
from rest_framework.permissions import IsAuthenticated
from rest_framework.request import Request
from rest_framework.response import Response

from config import outbound
from fleet.models import Role
from fleet.tenancy import current_membership

from .models import Alert, Delivery

MAX_ALERTS = 200


@extend_schema(responses=inline_serializer("Alerts", {"alerts": serializers.JSONField()}))
@api_view(["GET"])
@permission_classes([IsAuthenticated])
def recent(request: Request) -> Response:
    """`?limit=N` (at most 200) alerts of the current organisation, with their deliveries."""
    membership = current_membership(request)
    if membership is None:
        return Response({"alerts": []})
    try:
        limit = max(1, min(int(request.query_params.get("limit", 50)), MAX_ALERTS))
    except ValueError:
        limit = 50
    alerts = Alert.objects.filter(organisation_id=membership.organisation_id).prefetch_related(
        "deliveries"
    )[:limit]
    admin = membership.allows(Role.ADMIN)
    return Response(
        {
            "alerts": [
                {**a.to_dict(), "deliveries": [_delivery(d, admin) for d in a.deliveries.all()]}
                for a in alerts
            ]
        }
    )


def _delivery(delivery: Delivery, admin: bool) -> dict:
    """A webhook URL often holds the receiver's secret (in its path or query): only
    admins, who set it, see it."""
    hidden = delivery.channel == Delivery.Channel.WEBHOOK and not admin
    return {
        "recipient": outbound.HIDDEN if hidden else delivery.recipient,
        "channel": delivery.channel,
        "status": delivery.status,
        "attempts": delivery.attempts,
    }
