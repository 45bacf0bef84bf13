"""The site admin's drone and organisation forms check identity numbers as the API does."""

from __future__ import annotations

import pytest
from django.contrib import admin
from django.contrib.auth.models import User
from django.test import RequestFactory

from fleet.models import Drone, Organisation

pytestmark = pytest.mark.django_db


def form_for(model, obj=None):  # type: ignore[no-untyped-def]
    request = RequestFactory().get("/admin/")
    request.user = User.objects.create_superuser(f"root-{model.__name__}")
    return admin.site._registry[model].get_form(request, obj)


def test_the_drone_form_refuses_a_bad_serial_and_keeps_a_good_one(world):
    form_class = form_for(Drone, world.drone)
    data = {"organisation": world.org.pk, "drone_id": "ACME_1", "serial_number": "MFR1C1234"}
    bad = form_class(data=data, instance=world.drone)
    assert not bad.is_valid()
    assert "length character" in bad.errors["serial_number"][0]
    good = form_class(data={**data, "serial_number": "mfr1c123456789abc"}, instance=world.drone)
    assert good.is_valid(), good.errors
    assert good.cleaned_data["serial_number"] == "MFR1C123456789ABC"


def test_the_drone_form_keeps_the_eu_class_to_its_category(world):
    form_class = form_for(Drone, world.drone)
    data = {"organisation": world.org.pk, "drone_id": "ACME_1", "ua_type": 2}
    misfit = form_class(data={**data, "eu_category": 1, "eu_class": 6}, instance=world.drone)
    assert not misfit.is_valid()
    assert "specific category only" in misfit.errors["eu_class"][0]
    unknown = form_class(data={**data, "ua_type": 16}, instance=world.drone)
    assert not unknown.is_valid() and "ua_type" in unknown.errors
    fits = form_class(data={**data, "eu_category": 2, "eu_class": 6}, instance=world.drone)
    assert fits.is_valid(), fits.errors
    fits.save()
    world.drone.refresh_from_db()
    assert (world.drone.eu_category, world.drone.eu_class) == (2, 6)


def test_the_organisation_form_checks_the_eu_checksum_and_keeps_the_public_part(world):
    form_class = form_for(Organisation, world.org)
    data = {"name": "Acme", "slug": "acme", "envelope": "{}", "require_remote_id": "on"}
    bad = form_class(data={**data, "operator_id": "FIN87astrdge12k9-xyz"}, instance=world.org)
    assert not bad.is_valid()
    assert "checksum" in bad.errors["operator_id"][0]
    good = form_class(data={**data, "operator_id": "FIN87astrdge12k8-xyz"}, instance=world.org)
    assert good.is_valid(), good.errors
    good.save()
    world.org.refresh_from_db()
    assert world.org.operator_id == "FIN87astrdge12k8"
    # Saved again unchanged, the stored public part (its secret unknown) stays valid.
    again = form_class(data={**data, "operator_id": "FIN87astrdge12k8"}, instance=world.org)
    assert again.is_valid(), again.errors
