"""The airworthiness verdict of many drones at once (`verdicts`) is the verdict of each
alone, for every reason (maintenance due by hours, flights or days, a bulletin, a finding,
a retired pack chosen or reported, Remote ID failing, none), and the drone selection that
judges an organisation's candidates asks the database as often for 50 drones as for 5."""

from __future__ import annotations

from datetime import timedelta

import pytest
from django.db import connection
from django.test.utils import CaptureQueriesContext
from django.utils import timezone

from batteries.models import Battery
from checklists.models import Policy, Template
from fleet import airworthiness
from fleet.models import Drone, Organisation
from maintenance.models import Bulletin, LogEntry, Schedule
from missions.selection import nearest_available
from records.models import FlightRecord, Origin
from tests import factories
from tests.maintenance.support import flown
from tests.missions.conftest import online_drone, point_at

pytestmark = pytest.mark.django_db


def _schedule(drone: Drone, **rule: object) -> Schedule:
    """A schedule of the drone's own."""
    return Schedule.objects.create(
        organisation_id=drone.organisation_id, drone=drone, name=f"Task of {drone.drone_id}",
        **rule,
    )  # fmt: skip


def _signed(drone: Drone, at: object, **item: object) -> LogEntry:
    return LogEntry.objects.create(
        organisation_id=drone.organisation_id,
        drone=drone,
        drone_ident=drone.drone_id,
        item_name="done",
        signed_by_name="owner",
        notes="done",
        signed_at=at,
        **item,
    )


def _corrected(drone: Drone) -> None:
    """The drone's newest flight replaced by a correction of ten hours."""
    wrong = FlightRecord.objects.filter(drone=drone).order_by("-started_at").first()
    FlightRecord.objects.create(
        organisation_id=drone.organisation_id,
        drone=drone,
        drone_ident=drone.drone_id,
        origin=Origin.COMMAND,
        started_at=wrong.started_at,
        ended_at=wrong.started_at + timedelta(hours=10),
        duration_s=36000.0,
        corrects=wrong,
    )


def _fleet(world) -> dict[str, Drone]:  # type: ignore[no-untyped-def]
    """A drone for each reason, and drones where a near miss must not count."""
    org = world.org
    made = {name: online_drone(org, f"ACME_{name.upper()}") for name in CASES}
    flown(made["hours"], minutes=30, count=3)
    _schedule(made["hours"], every_hours=1.0)
    flown(made["flights"], minutes=5, count=2)
    _schedule(made["flights"], every_flights=2)
    Drone.objects.filter(pk=made["days"].pk).update(created_at=timezone.now() - timedelta(days=40))
    _schedule(made["days"], every_days=30)
    # Signed off after two of its three flights: one flight since, of two allowed.
    flown(made["signed"], minutes=5, count=3)
    signed = _schedule(made["signed"], every_flights=2)
    _signed(made["signed"], timezone.now() - timedelta(minutes=90), schedule=signed)
    # Its one flight corrected to ten hours: due by the correction's hours.
    flown(made["corrected"], minutes=5, count=1)
    _corrected(made["corrected"])
    _schedule(made["corrected"], every_hours=5.0)
    _schedule(made["soon"], every_days=30)
    Drone.objects.filter(pk=made["soon"].pk).update(created_at=timezone.now() - timedelta(days=28))
    for name in ("bulletin", "bulletin_signed", "model_schedule"):
        Drone.objects.filter(pk=made[name].pk).update(specs={"MODEL": " X8 "})
    Drone.objects.filter(pk=world.other_drone.pk).update(specs={"MODEL": "X8"})
    bulletin = Bulletin.objects.create(organisation=org, model="x8", title="Arms", text="Check.")
    _signed(made["bulletin_signed"], timezone.now(), bulletin=bulletin)
    Schedule.objects.create(organisation=org, model="X8 ", name="Yearly", every_days=365)
    Drone.objects.filter(pk=made["model_schedule"].pk).update(
        created_at=timezone.now() - timedelta(days=400)
    )
    Bulletin.objects.create(organisation=org, drone=made["finding"], title="Crack", text="Arm.")
    Battery.objects.create(
        organisation=org, serial="CHOSEN-1", drone=made["chosen_pack"], retired=True,
        retired_reason="health 55% below 70%",
    )  # fmt: skip
    Battery.objects.create(
        organisation=org, serial="SMART-7", retired=True, retired_reason="cycles 310 above 300"
    )
    Drone.objects.filter(pk=made["reported_pack"].pk).update(fc={"battery_serial": "SMART-7"})
    Drone.objects.filter(pk=made["remote_id"].pk).update(
        fc={"remote_id": {"ok": False, "error": "no GNSS fix for the broadcast"}}
    )
    return made


# Each drone of `_fleet` and a part of the reason that keeps it on the ground (None: none).
CASES = {
    "hours": "'Task of ACME_HOURS' overdue by 0.5 flight hours",
    "flights": "'Task of ACME_FLIGHTS' due now at 2 flights",
    "days": "'Task of ACME_DAYS' overdue by 10 days",
    "signed": None,
    "corrected": "'Task of ACME_CORRECTED' overdue by 5 flight hours",
    "soon": None,
    "bulletin": "service bulletin 'Arms' open since",
    "bulletin_signed": None,
    "model_schedule": "'Yearly' overdue by 35 days",
    "finding": "finding 'Crack' open since",
    "chosen_pack": "battery CHOSEN-1 retired: health 55% below 70%",
    "reported_pack": "battery SMART-7 retired: cycles 310 above 300",
    "remote_id": "Remote ID failing: no GNSS fix for the broadcast",
    "none": None,
}


def _remote_id_declared(world) -> None:  # type: ignore[no-untyped-def]
    """The organisation's drones have what Remote ID needs, but for the failing module."""
    world.org.operator_id = "FIN87astrdge12k8"
    world.org.save()
    Drone.objects.filter(organisation=world.org).update(
        remote_id_external=True, serial_number="1596F3A8B9C2D4E5"
    )


def test_the_verdicts_of_many_drones_are_each_drones_verdict(world):  # type: ignore[no-untyped-def]
    made = _fleet(world)
    _remote_id_declared(world)
    drones = list(
        Drone.objects.filter(pk__in=[*[d.pk for d in made.values()], world.other_drone.pk])
        .select_related("organisation")
        .order_by("drone_id")
    )
    together = airworthiness.verdicts(drones)
    assert together == {d.pk: airworthiness.verdict(d) for d in drones}
    by_name = {d.drone_id: together[d.pk] for d in drones}
    for name, reason in CASES.items():
        found = by_name[f"ACME_{name.upper()}"]
        if reason is None:
            assert found.airworthy, (name, found.reasons)
        else:
            assert not found.airworthy and any(reason in r for r in found.reasons), (name, found)
    # The other organisation's X8 owes nothing of this organisation's bulletins.
    assert not any("Arms" in r for r in together[world.other_drone.pk].reasons)


def test_a_drone_not_stored_is_judged_without_asking_for_its_records(world):  # type: ignore[no-untyped-def]
    drone = Drone(organisation=world.org, drone_id="ACME_NEW", specs={"MODEL": "x8"})
    Bulletin.objects.create(organisation=world.org, model="X8", title="Arms", text="Check.")
    found = airworthiness.verdict(drone)
    assert any("service bulletin 'Arms'" in r for r in found.reasons)
    assert airworthiness.verdicts([drone]) == {}


def _candidates(slug: str, count: int) -> Organisation:
    """An organisation requiring checklists with the automatic `airworthy` item (the
    batch's verdicts serve it too), and `count` online drones north of the target, each
    with a schedule, a pack and a flight: every third overdue, every fifth owing a
    bulletin."""
    org = factories.organisation(slug)
    Policy.objects.create(organisation=org, required=True, valid_minutes=30)
    Template.objects.create(
        organisation=org, name="Before flight", valid_minutes=30,
        items=[{"kind": "auto", "check": "airworthy", "threshold": None}],
    )  # fmt: skip
    Bulletin.objects.create(organisation=org, model="h6", title="Arms", text="Check.")
    for k in range(count):
        drone = online_drone(org, f"{slug.upper()}_{k:03d}", north=10.0 * (k + 1))
        Drone.objects.filter(pk=drone.pk).update(specs={"MODEL": "H6" if k % 5 == 4 else "X8"})
        flown(drone, minutes=20, count=1)
        _schedule(drone, every_hours=0.2 if k % 3 == 0 else 10.0)
        Battery.objects.create(organisation=org, serial=f"P{k}", drone=drone)
    return org


def _chosen(org: Organisation) -> list[str]:
    return [d.drone_id for d in nearest_available(org.pk, target=point_at(0, 0), count=2)]


def test_a_selection_asks_as_many_queries_for_fifty_drones_as_for_five(
    db,  # type: ignore[no-untyped-def]
    django_assert_max_num_queries,
):
    few = _candidates("few", 5)
    with CaptureQueriesContext(connection) as asked:
        assert _chosen(few) == ["FEW_001", "FEW_002"]  # FEW_000 is overdue
    many = _candidates("many", 50)
    with django_assert_max_num_queries(len(asked)):
        # MANY_000 overdue, MANY_003 overdue, MANY_004 owes the bulletin.
        assert _chosen(many) == ["MANY_001", "MANY_002"]
    assert len(asked) <= 12
