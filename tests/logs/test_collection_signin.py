"""A drone's sign-in on the log upload is throttled like a person's: wrong passwords count
per address and per drone id against LOGIN_RATE, and over it even the right one is
answered 429 until the window ends."""

from __future__ import annotations

import base64
import uuid

import pytest
from rest_framework.test import APIClient

from fleet.credentials import stored_hash
from fleet.models import Drone

pytestmark = pytest.mark.django_db
PASSWORD = "drone-secret-9"
URL = "/api/v1/logs/collect/"


def _address() -> str:
    """An address of its own per call: the counts outlive a test in the shared Redis."""
    return f"2001:db8::{uuid.uuid4().hex[:4]}:{uuid.uuid4().hex[:4]}"


def _offer(client: APIClient, drone_id: str, password: str, address: str) -> int:
    basic = base64.b64encode(f"{drone_id}:{password}".encode()).decode()
    response = client.post(
        URL, {}, format="json", REMOTE_ADDR=address, HTTP_AUTHORIZATION=f"Basic {basic}"
    )
    return response.status_code


@pytest.fixture
def drone(world, settings):  # type: ignore[no-untyped-def]
    settings.LOGIN_RATE = "3/min"
    drone_id = f"ACME_SIGN{uuid.uuid4().hex[:6].upper()}"
    return Drone.objects.create(
        organisation=world.org, drone_id=drone_id, mqtt_password_hash=stored_hash(PASSWORD)
    )


def test_wrong_drone_passwords_are_refused_with_429_after_the_limit(drone):
    client, address = APIClient(), _address()
    assert [_offer(client, drone.drone_id, "guess", address) for _ in range(3)] == [401] * 3
    # Over the limit: refused before the password is looked at, the right one too.
    assert _offer(client, drone.drone_id, PASSWORD, address) == 429
    # Per drone id as well: another address guessing the same drone is refused too.
    assert _offer(client, drone.drone_id, PASSWORD, _address()) == 429


def test_unknown_drone_ids_count_against_the_address(drone):
    client, address = APIClient(), _address()
    for _ in range(3):
        assert _offer(client, f"NOPE{uuid.uuid4().hex[:6]}", "guess", address) == 401
    assert _offer(client, drone.drone_id, PASSWORD, address) == 429
    # The drone itself, from its own address, is not locked out by another's guesses;
    # its offer is read (an empty one is refused for its fields, not its sign-in).
    assert _offer(client, drone.drone_id, PASSWORD, _address()) == 400
