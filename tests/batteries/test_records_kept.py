"""What a flight did to a pack, a checklist run and a maintenance sign-off are kept as
written: no model, API or deletion path changes or removes one silently."""

from __future__ import annotations

from datetime import timedelta

import pytest
from django.db.models import RestrictedError
from django.utils import timezone

from batteries.models import Battery, BatteryFlight
from checklists.models import Run
from fleet.models import Drone, Organisation
from tests.records.support import days_ago

from .test_batteries import _api, _choose, _fly

pytestmark = pytest.mark.django_db


def test_a_packs_flights_cannot_be_changed_or_deleted(world):
    _choose(world, "PACK-K", rated_wh=20.0)
    _fly(world.drone, days_ago(1), 0.9, 0.7)
    use = BatteryFlight.objects.get(battery__serial="PACK-K")
    use.cycles = 0.0
    with pytest.raises(PermissionError):
        use.save()
    with pytest.raises(PermissionError):
        use.delete()
    with pytest.raises(PermissionError):
        BatteryFlight.objects.filter(pk=use.pk).update(cycles=0.0)
    with pytest.raises(PermissionError):
        BatteryFlight.objects.filter(pk=use.pk).delete()
    assert BatteryFlight.objects.get(pk=use.pk).cycles > 0


def _run(drone: Drone) -> Run:
    now = timezone.now()
    return Run.objects.create(
        organisation=drone.organisation, drone=drone, template_name="Before flight",
        results=[], passed=True, at=now, expires_at=now + timedelta(minutes=30),
    )  # fmt: skip


def test_a_drone_with_checklist_runs_is_not_deleted_with_them(world):
    run = _run(world.drone)
    with pytest.raises(RestrictedError):
        Drone.objects.get(pk=world.drone.pk).delete()
    assert Run.objects.filter(pk=run.pk).exists()
    # Removing the whole organisation still takes its drones and their runs.
    _run(world.other_drone)
    Organisation.objects.get(pk=world.other_org.pk).delete()
    assert not Run.objects.filter(drone_id=world.other_drone.pk).exists()


@pytest.mark.parametrize(
    "path", ["/api/v1/drones/ACME_1/checklists/", "/api/v1/drones/ACME_1/maintenance/log/"]
)
def test_the_api_changes_no_run_or_sign_off(world, path):
    admin = _api(world.owner)
    assert admin.get(path).status_code == 200
    for method in (admin.put, admin.patch, admin.delete):
        assert method(path, {}, format="json").status_code == 405


def test_a_correction_moves_the_flight_to_the_pack_it_names(world):
    _choose(world, "PACK-A", rated_wh=20.0)
    record = _fly(world.drone, days_ago(1), 0.9, 0.7)
    made = _api(world.operator).post(
        "/api/v1/batteries/", {"serial": "PACK-B", "rated_energy_wh": 20.0}, format="json"
    )
    assert made.status_code == 201, made.content
    first = Battery.objects.get(serial="PACK-A")
    assert first.flights == 1 and first.cycles == pytest.approx(0.2)
    url = f"/api/v1/flights/{record.pk}/corrections/"
    body = {"reason": "flown on the spare pack", "battery": "PACK-B"}
    moved = _api(world.owner).post(url, body, format="json")
    assert moved.status_code == 201, moved.content
    first, second = Battery.objects.get(serial="PACK-A"), Battery.objects.get(serial="PACK-B")
    assert (first.flights, first.cycles) == (0, 0.0)
    assert second.flights == 1 and second.cycles == pytest.approx(0.2)
    # Correcting the charge again counts the newest figures once, on the same pack.
    again = _api(world.owner).post(
        f"/api/v1/flights/{moved.json()['id']}/corrections/",
        {"reason": "the end charge was misread", "battery_end": 0.5},
        format="json",
    )
    assert again.status_code == 201, again.content
    second = Battery.objects.get(serial="PACK-B")
    assert second.flights == 1 and second.cycles == pytest.approx(0.4)
    assert BatteryFlight.objects.count() == 3  # every version's use kept
