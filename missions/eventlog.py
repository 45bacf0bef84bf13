"""The drones' important happenings as one log line each, on logger `skyhive.events` and
tagged EVENT_TAG: drones coming online and going offline, alarms, missions starting and
ending. `make run` shows these lines among the warnings and errors (scripts/runlog.py);
everything else the processes log goes to their log files."""

from __future__ import annotations

import logging
from collections.abc import Sequence

from django.db import transaction

log = logging.getLogger("skyhive.events")
EVENT_TAG = "[event]"


def note(text: str) -> None:
    """Log `text` once the current transaction commits (at once outside one): a rolled
    back change never shows up as an event."""
    transaction.on_commit(lambda: log.info("%s %s", EVENT_TAG, text))


def drones_online(sender: object, drone_ids: Sequence[str] = (), **kwargs: object) -> None:
    if drone_ids:
        note(f"online: {', '.join(drone_ids)}")


def drones_offline(sender: object, drone_ids: Sequence[str] = (), **kwargs: object) -> None:
    if drone_ids:
        note(f"offline: {', '.join(drone_ids)}")
