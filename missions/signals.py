"""React at once when a drone comes online (a paused mission may take it, no beat wait) or
goes offline mid-mission (the mission shows it; a replacement follows the grace period)."""

from __future__ import annotations

from django.db import transaction
from django.dispatch import Signal

from .models import Mission, MissionStatus

# Sent for a CRITICAL alarm no mission could record (the drone flies none), so what
# watches alarms still hears it. Arguments: drone (fleet.models.Drone), alarm
# (onboard.protocol.Alarm).
critical_alarm_outside_mission = Signal()


def resume_when_drones_come_online(sender, organisation_ids, **kwargs) -> None:  # type: ignore[no-untyped-def]
    if Mission.objects.filter(
        status=MissionStatus.PAUSED, organisation_id__in=organisation_ids
    ).exists():
        from .tasks import resume_paused

        transaction.on_commit(resume_paused.delay)


def replace_when_drones_go_offline(sender, drone_ids, **kwargs) -> None:  # type: ignore[no-untyped-def]
    from .offline import note_offline

    note_offline(drone_ids)
