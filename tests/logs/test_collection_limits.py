"""The ground's bounds on the logs a drone uploads by itself: the size cap before any
byte, the number of unfinished uploads, and the place an abandoned one stops holding."""

from __future__ import annotations

import hashlib
from datetime import UTC, datetime, timedelta

import pytest

from fleet.models import Drone
from logs import collection
from logs.models import CollectedLog

pytestmark = pytest.mark.django_db

FLOWN = datetime(2026, 12, 1, 10, tzinfo=UTC)


def _offer(name: str, size: int = 100) -> collection.Offer:
    return collection.Offer(
        kind="onboard",
        name=name,
        size=size,
        sha256=hashlib.sha256(name.encode()).hexdigest(),
        flight_started_at=FLOWN,
        flight_ended_at=FLOWN + timedelta(minutes=3),
    )


@pytest.fixture
def drone(world, settings, tmp_path):  # type: ignore[no-untyped-def]
    settings.LOGS_DIR = str(tmp_path)
    settings.LOG_COLLECT_MAX_OPEN = 1
    settings.LOG_COLLECT_MAX_BYTES = 1000
    return Drone.objects.create(organisation=world.org, drone_id="ACME_LIM")


def test_an_offer_over_the_size_cap_is_refused_before_any_byte(drone):
    with pytest.raises(collection.CollectionRefused) as refused:
        collection.offer(drone, _offer("big.dfi", size=1001))
    assert (refused.value.code, refused.value.status) == ("too_large", 413)
    assert not CollectedLog.objects.exists()


def test_unfinished_uploads_are_bounded_and_an_abandoned_one_gives_its_place_back(drone):
    first = collection.offer(drone, _offer("one.dfi"))
    collection.receive(drone, str(first.pk), 0, b"x" * 40)
    assert first.part_path.stat().st_size == 40
    with pytest.raises(collection.CollectionRefused) as refused:
        collection.offer(drone, _offer("two.dfi"))
    assert (refused.value.code, refused.value.status) == ("too_many_open", 429)
    # The same log offered again is its own upload, at the ground's offset.
    assert collection.offer(drone, _offer("one.dfi")).received == 40

    week = timedelta(days=7, minutes=1)
    CollectedLog.objects.filter(pk=first.pk).update(created_at=first.created_at - week)
    second = collection.offer(drone, _offer("two.dfi"))
    assert list(CollectedLog.objects.values_list("name", flat=True)) == ["two.dfi"]
    assert not first.part_path.exists() and second.received == 0


def test_a_chunk_at_another_offset_changes_nothing(drone):
    row = collection.offer(drone, _offer("one.dfi"))
    collection.receive(drone, str(row.pk), 0, b"x" * 40)
    for offset in (0, 30, 41):
        with pytest.raises(collection.CollectionRefused) as refused:
            collection.receive(drone, str(row.pk), offset, b"y" * 10)
        assert (refused.value.code, refused.value.received) == ("bad_offset", 40)
    assert row.part_path.read_bytes() == b"x" * 40
