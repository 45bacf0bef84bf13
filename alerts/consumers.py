"""`/ws/alerts/?org=<slug>`: the banner every page shows; the organisation's recent alerts
first, then each new one as it is raised."""

from __future__ import annotations

from datetime import timedelta
from typing import Any

from channels.db import database_sync_to_async
from django.conf import settings
from django.utils import timezone

from fleet.consumers import GroupConsumer, membership_for_query
from fleet.models import Membership

from .models import Alert
from .raising import group_name


@database_sync_to_async
def _recent(organisation_id: int) -> list[dict]:
    since = timezone.now() - timedelta(seconds=settings.ALERT_RECENT_S)
    alerts = Alert.objects.filter(organisation_id=organisation_id, at__gte=since)[:20]
    return [a.to_dict() for a in alerts]


class AlertConsumer(GroupConsumer):
    async def authorise(self, user: Any) -> Membership | None:
        return await membership_for_query(user, self.scope)

    def group_for(self, membership: Membership) -> str:
        return group_name(membership.organisation_id)

    async def welcome(self, membership: Membership) -> None:
        await self.send_json(
            {"type": "recent", "alerts": await _recent(membership.organisation_id)}
        )

    alert_raised = GroupConsumer.send_payload
