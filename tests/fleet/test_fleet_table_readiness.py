"""The fleet table's readiness column over a page of many drones: the same verdicts as
judging each drone alone, with the battery reason read for the whole page at once."""

from __future__ import annotations

import pytest
from django.db import connection
from django.test.utils import CaptureQueriesContext

from batteries.models import Battery
from fleet import airworthiness, listing
from fleet.models import Drone

pytestmark = pytest.mark.django_db

DRONES = 200


def _fleet(world) -> list[Drone]:  # type: ignore[no-untyped-def]
    """DRONES drones: every third reports its pack's serial (every other of those retired),
    every fifth of the rest carries a chosen pack (every other retired); and one drone of
    another organisation reporting a serial this one retired."""
    drones = Drone.objects.bulk_create(
        [
            Drone(
                organisation=world.org,
                drone_id=f"BULK_{i:04d}",
                fc={"protocol": "mavlink", **({"battery_serial": f"FC-{i}"} if i % 3 == 0 else {})},
            )
            for i in range(DRONES)
        ]
    )
    packs = []
    for i, drone in enumerate(drones):
        if i % 3 == 0:
            packs.append(Battery(organisation=world.org, serial=f"FC-{i}", reported=True))
        elif i % 5 == 0:
            packs.append(Battery(organisation=world.org, serial=f"CHOSEN-{i}", drone=drone))
        else:
            continue
        if i % 2 == 0:
            packs[-1].retired, packs[-1].retired_reason = True, f"health {i} % below 80%"
    Battery.objects.bulk_create(packs)
    Drone.objects.filter(pk=world.other_drone.pk).update(
        fc={"protocol": "mavlink", "battery_serial": "FC-0"}
    )
    return list(Drone.objects.filter(organisation=world.org).select_related("organisation"))


def test_the_verdicts_of_many_are_each_drones_own(world):
    drones = _fleet(world)
    other = Drone.objects.select_related("organisation").get(pk=world.other_drone.pk)
    many = airworthiness.verdicts([*drones, other])
    assert {pk: v.to_dict() for pk, v in many.items()} == {
        d.pk: airworthiness.verdict(d).to_dict() for d in [*drones, other]
    }
    retired = [pk for pk, v in many.items() if not v.airworthy]
    # Reporting: 0, 6, … 198 (34); chosen: the tens that are not multiples of 3 (13).
    assert len(retired) == 34 + 13
    assert many[other.pk].airworthy  # FC-0 is retired in another organisation only


def test_a_table_page_of_200_reads_the_battery_reason_in_two_queries(
    world, django_assert_max_num_queries
):
    _fleet(world)
    query = listing.TableQuery(page_size=DRONES)
    with CaptureQueriesContext(connection) as seen:
        page = listing.table_page(world.org.pk, query)
    assert len(page["results"]) == DRONES
    assert sum('"batteries_battery"' in q["sql"] for q in seen.captured_queries) <= 2
    # At most the maintenance reason's own reading per drone (docs/maintenance.md), two
    # queries, on top of a fixed handful for the page.
    with django_assert_max_num_queries(2 * DRONES + 10):
        listing.table_page(world.org.pk, query)
    readiness = {r["drone_id"]: r["readiness"] for r in page["results"]}
    assert readiness["BULK_0000"]["reasons"] == ["battery FC-0 retired: health 0 % below 80%"]
    assert readiness["BULK_0010"]["reasons"] == ["battery CHOSEN-10 retired: health 10 % below 80%"]
    assert readiness["BULK_0003"]["airworthy"] and readiness["BULK_0005"]["airworthy"]
