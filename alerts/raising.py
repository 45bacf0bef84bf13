"""Raise an alert once per happening: store it, show it on every open page of the
organisation, and queue one delivery per recipient after the transaction commits."""

from __future__ import annotations

import logging
from uuid import UUID

from asgiref.sync import async_to_sync
from channels.layers import get_channel_layer
from django.db import IntegrityError, transaction

from accounts.organisation import settings_of
from fleet.models import Organisation

from .models import Alert, Delivery

log = logging.getLogger(__name__)

SEVERITY = {
    Alert.Kind.CRITICAL_ALARM: Alert.Severity.CRITICAL,
    Alert.Kind.REPLACEMENT: Alert.Severity.WARNING,
    Alert.Kind.DRONE_LOST: Alert.Severity.CRITICAL,
    Alert.Kind.MISSION_COMPLETED: Alert.Severity.INFO,
    Alert.Kind.MISSION_FAILED: Alert.Severity.CRITICAL,
    Alert.Kind.REMOTE_ID: Alert.Severity.WARNING,
    Alert.Kind.LOG_TREND: Alert.Severity.WARNING,
    Alert.Kind.WIND: Alert.Severity.WARNING,
    Alert.Kind.MAINTENANCE: Alert.Severity.WARNING,
}


def group_name(organisation_id: int) -> str:
    return f"alerts-{organisation_id}"


def raise_alert(
    organisation: Organisation,
    kind: str,
    title: str,
    *,
    source: str,
    detail: str = "",
    drone_id: str = "",
    mission_id: UUID | str | None = None,
) -> Alert | None:
    """The new alert, or None when this source already raised one."""
    try:
        with transaction.atomic():
            alert = Alert.objects.create(
                organisation=organisation,
                kind=kind,
                severity=SEVERITY[kind],
                title=title[:200],
                detail=detail[:500],
                drone_id=drone_id,
                mission_id=mission_id,
                source=source[:200],
            )
            deliveries = _deliveries(alert, settings_of(organisation).alert_recipients)
    except IntegrityError:
        return None
    transaction.on_commit(lambda: _announce(alert, deliveries))
    return alert


def _deliveries(alert: Alert, recipients: list[str]) -> list[Delivery]:
    return Delivery.objects.bulk_create(
        Delivery(alert=alert, channel=_channel(recipient), recipient=recipient)
        for recipient in recipients
    )


def _channel(recipient: str) -> str:
    if recipient.startswith(("http://", "https://")):
        return Delivery.Channel.WEBHOOK
    return Delivery.Channel.EMAIL


def _announce(alert: Alert, deliveries: list[Delivery]) -> None:
    from .tasks import deliver

    push(alert)
    for delivery in deliveries:
        deliver.delay(str(delivery.pk))


def push(alert: Alert) -> None:
    """Best effort: a page that misses it shows it from the recent list when it connects."""
    layer = get_channel_layer()
    if layer is None:
        return
    try:
        async_to_sync(layer.group_send)(
            group_name(alert.organisation_id),
            {"type": "alert.raised", "payload": {"type": "alert", "alert": alert.to_dict()}},
        )
    except Exception:  # noqa: BLE001 - Redis away must never lose the stored alert
        log.warning("could not push alert %s", alert.pk, exc_info=True)
