"""Warnings before a task grounds a drone: one WARNING alert when a recorded flight brings
a schedule within its margin, one when it falls due, never twice; the beat's sweep finds
what calendar time brought."""

from __future__ import annotations

from datetime import timedelta

import pytest
from django.utils import timezone

from alerts.models import Alert
from fleet.models import Drone
from maintenance import alerting
from maintenance.models import Schedule

from .support import flown

pytestmark = pytest.mark.django_db


def test_recorded_flights_raise_one_due_soon_then_one_due_warning(
    world, settings, django_capture_on_commit_callbacks
):
    settings.MAINTENANCE_DUE_SOON_FRACTION = 0.25
    Schedule.objects.create(
        organisation=world.org, drone=world.drone, name="Props", every_flights=4
    )
    with django_capture_on_commit_callbacks(execute=True):
        flown(world.drone, minutes=10, count=3)
    alert = Alert.objects.get()
    assert (alert.kind, alert.severity) == (Alert.Kind.MAINTENANCE, Alert.Severity.WARNING)
    assert alert.title == "ACME_1: maintenance 'Props' due soon"
    assert alert.detail == "3 of 4 flights" and alert.drone_id == "ACME_1"
    with django_capture_on_commit_callbacks(execute=True):
        flown(world.drone, minutes=10)
    assert alerting.sweep() == 0
    titles = sorted(Alert.objects.values_list("title", flat=True))
    assert titles == [
        "ACME_1: maintenance 'Props' due soon",
        "ACME_1: maintenance 'Props' due: the drone may not fly until it is signed off",
    ]


def test_the_sweep_warns_of_a_calendar_task_coming_due(world, settings):
    settings.MAINTENANCE_DUE_SOON_FRACTION = 0.1
    Schedule.objects.create(organisation=world.org, model="X8", name="Yearly", every_days=365)
    Drone.objects.filter(pk=world.drone.pk).update(
        specs={"MODEL": "X8"}, created_at=timezone.now() - timedelta(days=340)
    )
    assert alerting.sweep() == 1
    assert alerting.sweep() == 0
    assert Alert.objects.get().detail == "340 of 365 days"
