"""A drone flying with a failing Remote ID: one WARNING alert per drone every
REMOTE_ID_ALERT_EVERY_S while its heartbeats say so (docs/remote-id.md). The flight goes
on: landing at once could be the greater hazard, and the pilot decides."""

from __future__ import annotations

from datetime import datetime

from django.conf import settings

from fleet.models import Organisation
from fleet.signals import remote_id_failing

from .models import Alert
from .raising import raise_alert


def connect() -> None:
    remote_id_failing.connect(on_remote_id_failing, dispatch_uid="alerts-remote-id")


def _window(seen: datetime) -> int:
    """The alert window a heartbeat falls in: the same window raises one alert."""
    return int(seen.timestamp() // max(1, settings.REMOTE_ID_ALERT_EVERY_S))


def on_remote_id_failing(sender: object, failing: list, **kwargs: object) -> None:
    organisations = Organisation.objects.in_bulk({org for _drone, org, _error, _seen in failing})
    for drone_id, organisation_id, error, seen in failing:
        organisation = organisations.get(organisation_id)
        if organisation is None:
            continue
        raise_alert(
            organisation,
            Alert.Kind.REMOTE_ID,
            f"{drone_id} flies with a failing Remote ID: {error or 'no reason given'}",
            source=f"remote-id:{drone_id}:{_window(seen)}",
            detail="Its identity may not be broadcast; land it when it is safe to.",
            drone_id=drone_id,
        )
