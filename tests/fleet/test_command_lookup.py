"""The drone lookup of a command (fleet.commands.find_drone, its SQL built once per shape by
fleet.compiled) finds what the isolation rule lets the user see, with the user's role, and
the rules' reads it carries give the verdicts the rules give when they read for themselves;
a drone that may go is judged without a statement beyond its lookup."""

from __future__ import annotations

from datetime import timedelta

import pytest
from django.utils import timezone

from batteries.models import Battery
from checklists import gate
from checklists.models import Policy, Run
from fleet import airworthiness, commands, tenancy
from fleet.models import Drone, Membership, Role
from maintenance.models import Bulletin, LogEntry, Schedule
from tests import factories

pytestmark = pytest.mark.django_db

COMMANDS = ("arm", "takeoff", "disarm", "land")


def _found(user, drone_id: str, command: str) -> Drone | None:  # type: ignore[no-untyped-def]
    try:
        return commands.find_drone(user, drone_id, command)
    except commands.CommandRefused as refusal:
        assert refusal.status == 404
        return None


@pytest.mark.parametrize("command", COMMANDS)
def test_each_user_finds_the_drones_of_their_organisations_with_their_role(world, command):
    both = factories.person(world.org, Role.OPERATOR, "both")
    Membership.objects.create(user=both, organisation=world.other_org, role=Role.VIEWER)
    expected = {
        (world.operator, "ACME_1"): Role.OPERATOR,
        (world.viewer, "ACME_1"): Role.VIEWER,
        (world.outsider, "ACME_1"): None,
        (world.outsider, world.other_drone.drone_id): Role.ADMIN,
        (world.operator, world.other_drone.drone_id): None,
        (both, "ACME_1"): Role.OPERATOR,
        (both, world.other_drone.drone_id): Role.VIEWER,
        (world.operator, "NO_SUCH_DRONE"): None,
    }
    for (user, drone_id), role in expected.items():
        found = _found(user, drone_id, command)
        assert (found and found.member_role) == role, (user, drone_id)
        if found is not None:
            stored = Drone.objects.select_related("organisation").get(drone_id=drone_id)
            assert found.pk == stored.pk and found.organisation == stored.organisation
            assert found.organisation.slug == stored.organisation.slug
            assert found.fc == stored.fc and found.specs == stored.specs


@pytest.mark.parametrize("command", COMMANDS)
def test_a_user_bound_to_one_organisation_finds_its_drones_only(world, command):
    both = factories.person(world.org, Role.OPERATOR, "both")
    Membership.objects.create(user=both, organisation=world.other_org, role=Role.ADMIN)
    tenancy.bind(both, world.other_org.pk)
    assert _found(both, "ACME_1", command) is None
    assert _found(both, world.other_drone.drone_id, command).member_role == Role.ADMIN


def _judged(world, drone: Drone) -> tuple:  # type: ignore[no-untyped-def]
    """(verdict, checklist refusal) from the arm's lookup and from a plain read."""
    looked_up = commands.find_drone(world.operator, drone.drone_id, "arm")
    plain = Drone.objects.select_related("organisation").get(pk=drone.pk)
    by_lookup = (airworthiness.verdict(looked_up), gate.refusal(looked_up))
    by_reading = (airworthiness.verdict(plain), gate.refusal(plain))
    assert by_lookup == by_reading
    return by_lookup


def test_a_drone_that_may_go_is_judged_from_its_lookup_alone(world, django_assert_num_queries):
    drone = world.drone
    Battery.objects.create(organisation=world.org, serial="SPARE", retired=True)
    Schedule.objects.create(
        organisation=world.other_org, drone=world.other_drone, name="Other org", every_days=1
    )
    looked_up = commands.find_drone(world.operator, drone.drone_id, "arm")
    with django_assert_num_queries(0):
        assert airworthiness.verdict(looked_up).airworthy
        assert gate.refusal(looked_up) is None


def test_retired_packs_are_judged_as_a_read_judges_them(world):
    drone = world.drone
    assert _judged(world, drone)[0].airworthy
    Battery.objects.create(organisation=world.org, serial="P1", retired=True, retired_reason="old")
    assert _judged(world, drone)[0].airworthy  # a retired pack the drone does not carry
    Drone.objects.filter(pk=drone.pk).update(fc={"battery_serial": "P1"})
    verdict = _judged(world, drone)[0]
    assert verdict.reasons == ["battery P1 retired: old"]
    Drone.objects.filter(pk=drone.pk).update(fc={"battery_serial": "P2"})
    Battery.objects.create(organisation=world.org, serial="P2")
    assert _judged(world, drone)[0].airworthy  # the reported pack is in service
    Drone.objects.filter(pk=drone.pk).update(fc={"battery_serial": ""})
    Battery.objects.filter(serial="P1").update(drone=drone)
    assert _judged(world, drone)[0].reasons == ["battery P1 retired: old"]  # the chosen one


def test_maintenance_is_judged_as_a_read_judges_it(world):
    drone = world.drone
    Drone.objects.filter(pk=drone.pk).update(
        specs={"MODEL": "Hexa X"}, created_at=timezone.now() - timedelta(days=3)
    )
    Schedule.objects.create(organisation=world.org, name="Quad", model="Quad Y", every_days=1)
    assert _judged(world, drone)[0].airworthy  # another model's schedule
    Schedule.objects.create(organisation=world.org, name="Hexa", model="hexa x ", every_days=1)
    assert _judged(world, drone)[0].reasons[0].startswith("maintenance due: 'Hexa'")
    Schedule.objects.all().delete()
    bulletin = Bulletin.objects.create(
        organisation=world.org, model="Hexa X", title="Props", text="Replace the props."
    )
    assert _judged(world, drone)[0].reasons[0].startswith("maintenance due: service bulletin")
    LogEntry.objects.create(
        organisation=world.org,
        drone=drone,
        drone_ident=drone.drone_id,
        bulletin=bulletin,
        item_name="Props",
        signed_by_name="owner",
        notes="done",
    )
    assert _judged(world, drone)[0].airworthy
    looked_up = commands.find_drone(world.operator, drone.drone_id, "arm")
    assert looked_up.maintenance_may_owe is False  # signed off for this drone


def _run(world, drone: Drone, passed: bool, age: timedelta) -> None:  # type: ignore[no-untyped-def]
    at = timezone.now() - age
    Run.objects.create(
        organisation=world.org,
        drone=drone,
        template_name="Pre-flight",
        results=[],
        passed=passed,
        at=at,
        expires_at=at + timedelta(minutes=30),
    )


def test_the_checklist_gate_is_judged_as_a_read_judges_it(world, settings):
    drone = world.drone
    settings.CHECKLIST_REQUIRED_DEFAULT = False
    assert _judged(world, drone)[1] is None
    settings.CHECKLIST_REQUIRED_DEFAULT = True
    assert "no checklist has been run" in _judged(world, drone)[1]
    _run(world, drone, passed=True, age=timedelta(hours=1))
    assert "has expired" in _judged(world, drone)[1]
    _run(world, drone, passed=False, age=timedelta(minutes=1))
    assert "failed" in _judged(world, drone)[1]
    _run(world, drone, passed=True, age=timedelta(seconds=1))
    assert _judged(world, drone)[1] is None
    unchecked = factories.drone(world.org, "ACME_2")
    Policy.objects.create(organisation=world.org, required=False, valid_minutes=30)
    assert _judged(world, unchecked)[1] is None
    Policy.objects.filter(organisation=world.org).update(required=True)
    assert "no checklist has been run" in _judged(world, unchecked)[1]


def test_a_stand_in_missing_from_the_query_is_refused_when_compiled(world):
    from fleet import compiled

    queryset = Drone.objects.filter(drone_id="\x00stand-in")[:1]
    with pytest.raises(ValueError, match="organisation"):
        compiled.Compiled(queryset, {"drone_id": "\x00stand-in", "organisation": -7})
    lookup = compiled.Compiled(queryset, {"drone_id": "\x00stand-in", "at": -7}, optional=("at",))
    assert lookup.first(drone_id="ACME_1").pk == world.drone.pk
    assert lookup.first(drone_id="NO_SUCH_DRONE") is None
