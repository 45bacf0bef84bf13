"""A running mission on the outage stack's own database (tests/support/outage.py).

Run as `python -m tests.support.outage_scene <failing drone> <spare drone>` with that
stack's environment: creates an organisation, the failing drone flying a five-step
mission (its assignment accepted) and a spare drone online nearby, charged, free; prints
`{"mission_id", "assignment_id", "steps"}` as JSON.
"""

from __future__ import annotations

import json
import sys

import django


def main(failing_id: str, spare_id: str) -> dict:
    django.setup()
    from fleet.models import Drone, Organisation
    from missions.creation import create_mission
    from missions.models import Assignment
    from missions.startstop import start_mission
    from tests.missions.planning import point_at

    org, _ = Organisation.objects.get_or_create(slug="outage", defaults={"name": "Outage"})
    for drone_id, north in ((failing_id, 0.0), (spare_id, 30.0)):
        lat, lon = point_at(north, 0.0)
        Drone.objects.update_or_create(
            drone_id=drone_id,
            defaults={
                "organisation": org,
                "online": True,
                "lat": lat,
                "lon": lon,
                "alt": 0.0,
                "battery_remaining": 0.95,
                "battery_voltage": 16.4,
            },
        )
    # Every scene's drones share this organisation and database: the reservations an
    # earlier scene's flights left (its drones are no longer flown) are ended.
    from django.utils import timezone

    from airspace.models import Reservation

    Reservation.objects.filter(organisation=org, ended_at__isnull=True).exclude(
        drone__drone_id__in=[failing_id, spare_id]
    ).update(ended_at=timezone.now(), end_reason="scene reset")
    steps = [{"command": "arm"}, {"command": "takeoff", "params": {"altitude": 10}}]
    for north in (20.0, 40.0):
        lat, lon = point_at(north, 10.0)
        steps.append({"command": "navigate", "params": {"lat": lat, "lon": lon}})
    steps.append({"command": "land"})
    mission = create_mission(organisation=org, name=f"outage {failing_id}", steps=steps)
    assignment = start_mission(mission, drone=Drone.objects.get(drone_id=failing_id)).assignment
    Assignment.objects.filter(pk=assignment.pk).update(status=Assignment.Status.ACCEPTED)
    return {
        "mission_id": str(mission.pk),
        "assignment_id": str(assignment.pk),
        "steps": [{"index": i, "command": s["command"]} for i, s in enumerate(steps)],
    }


if __name__ == "__main__":
    print(json.dumps(main(sys.argv[1], sys.argv[2])))
