"""REST: the organisation's recent alerts, newest first."""

from __future__ import annotations

from drf_spectacular.utils import extend_schema, inline_serializer
from rest_framework import serializers
from rest_framework.decorators import api_view, permission_classes
from rest_framework.permissions import IsAuthenticated
from rest_framework.request import Request
from rest_framework.response import Response

from fleet.tenancy import current_membership

from .models import Alert

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
    return Response(
        {
            "alerts": [
                {
                    **a.to_dict(),
                    "deliveries": [
                        {"recipient": d.recipient, "status": d.status, "attempts": d.attempts}
                        for d in a.deliveries.all()
                    ],
                }
                for a in alerts
            ]
        }
    )
