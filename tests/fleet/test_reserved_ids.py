"""The broker's own account names are never drone ids: provisioning, the admin's form and
the API refuse them, whatever their case, and nothing changes."""

import pytest
from django.contrib import admin
from django.contrib.auth.models import User
from django.core.management import call_command
from django.core.management.base import CommandError
from django.test import RequestFactory
from rest_framework.test import APIClient

from fleet import credentials
from fleet.models import Drone

RESERVED = ["ground", "GROUND", "Admin", "guest", "Ingest-Svc"]


@pytest.fixture
def service_users(settings):
    settings.MQTT_SERVICE_USERS = ["ground", "ingest-svc"]


@pytest.mark.parametrize("drone_id", RESERVED)
def test_provisioning_refuses_a_reserved_id(world, service_users, drone_id):
    with pytest.raises(credentials.ProvisioningError, match="Reserved drone id"):
        credentials.provision(drone_id, world.org.slug)
    with pytest.raises(CommandError, match=f"Reserved drone id.*{drone_id}"):
        call_command("provision_drone", drone_id, "--org", world.org.slug)
    assert not Drone.objects.filter(drone_id__iexact=drone_id).exists()


def test_a_batch_with_one_reserved_id_is_refused_whole(world, service_users):
    with pytest.raises(credentials.ProvisioningError, match="'guest'"):
        credentials.provision_many(["ACME_7", "guest"], world.org.slug)
    assert not Drone.objects.filter(drone_id="ACME_7").exists()


def test_a_name_merely_containing_a_reserved_word_is_fine(world, service_users):
    drone = Drone(organisation=world.org, drone_id="ground_station_2")
    drone.full_clean()


@pytest.mark.parametrize("drone_id", RESERVED)
def test_the_admin_form_names_the_field(world, service_users, drone_id):
    request = RequestFactory().get("/admin/fleet/drone/add/")
    request.user = User.objects.create_superuser(f"root-{drone_id}")
    form_class = admin.site._registry[Drone].get_form(request)
    form = form_class(data={"organisation": world.org.pk, "drone_id": drone_id})
    assert not form.is_valid()
    assert "reserved" in form.errors["drone_id"][0]
    assert not Drone.objects.filter(drone_id__iexact=drone_id).exists()


def test_the_api_answers_400_naming_the_field_for_a_reserved_drone(world, service_users):
    # A drone that was named before the names were reserved.
    Drone.objects.create(organisation=world.org, drone_id="guest")
    owner = APIClient()
    owner.force_authenticate(world.owner)
    response = owner.post("/api/v1/drones/guest/credentials/")
    assert response.status_code == 400
    assert "Reserved drone id" in response.json()["fields"]["drone_id"][0]
    assert Drone.objects.get(drone_id="guest").mqtt_password_hash == ""
