"""Deliver one alert to one recipient: an e-mail through Django's mail backend, or a JSON
POST to a webhook (only where `config.outbound` allows it). A delivery is attempted under a
row lock and marked delivered at once, so a retried task never sends it twice; webhooks
also get the delivery's id as an Idempotency-Key header, for a receiver whose answer was
lost on the way back."""

from __future__ import annotations

import http.client
import json

from django.conf import settings
from django.core.mail import send_mail
from django.db import transaction
from django.utils import timezone

from config import outbound

from .models import Alert, Delivery


class DeliveryError(Exception):
    """The recipient did not take it; the message says why."""


def attempt(delivery_id: str) -> str:
    """One try: "delivered", "done" (nothing left to do), "retry" or "failed"."""
    with transaction.atomic():
        delivery = (
            Delivery.objects.select_for_update()
            .select_related("alert")
            .filter(pk=delivery_id)
            .first()
        )
        if delivery is None or delivery.status != Delivery.Status.PENDING:
            return "done"
        delivery.attempts += 1
        try:
            send(delivery)
        except DeliveryError as exc:
            delivery.last_error = str(exc)[:500]
            exhausted = delivery.attempts >= settings.ALERT_MAX_ATTEMPTS
            if exhausted:
                delivery.status = Delivery.Status.FAILED
            delivery.save(update_fields=["attempts", "last_error", "status"])
            return "failed" if exhausted else "retry"
        delivery.status = Delivery.Status.DELIVERED
        delivery.delivered_at = timezone.now()
        delivery.last_error = ""
        delivery.save(update_fields=["attempts", "last_error", "status", "delivered_at"])
        return "delivered"


def send(delivery: Delivery) -> None:
    if delivery.channel == Delivery.Channel.EMAIL:
        _email(delivery.alert, delivery.recipient)
    else:
        _webhook(delivery, delivery.recipient)


def _email(alert: Alert, recipient: str) -> None:
    subject = f"[Skyhive] {alert.get_severity_display()}: {alert.title}"
    body = "\n".join(
        line
        for line in (
            alert.title,
            alert.detail,
            f"Drone: {alert.drone_id}" if alert.drone_id else "",
            f"Mission: {alert.mission_id}" if alert.mission_id else "",
            f"At: {alert.at:%Y-%m-%d %H:%M:%S %Z}",
        )
        if line
    )
    try:
        send_mail(subject, body, settings.DEFAULT_FROM_EMAIL, [recipient])
    except Exception as exc:  # noqa: BLE001 - any backend failure is one failed attempt
        raise DeliveryError(f"mail not sent: {exc}") from exc


def _webhook(delivery: Delivery, url: str) -> None:
    body = json.dumps({"alert": delivery.alert.to_dict()}).encode()
    headers = {
        "Content-Type": "application/json",
        "Idempotency-Key": str(delivery.pk),
        "User-Agent": "Skyhive alerts",
    }
    try:
        status = outbound.post(url, body, headers, timeout=settings.ALERT_WEBHOOK_TIMEOUT_S)
    except outbound.Refused as exc:
        raise DeliveryError(f"the webhook is refused: {exc}") from exc
    except (OSError, http.client.HTTPException) as exc:
        raise DeliveryError(f"the webhook could not be reached: {exc}") from exc
    if 300 <= status < 400:
        raise DeliveryError(f"the webhook answered {status} (redirects are not followed)")
    if not 200 <= status < 300:
        raise DeliveryError(f"the webhook answered {status}")
