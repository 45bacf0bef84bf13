"""Recorded video is kept for a period and, per organisation, up to a size in all."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta

import pytest
from django.core.files.base import ContentFile

from livevideo.models import VideoRecording, VideoRetention
from livevideo.retention import prune, set_rule
from tests.logs.test_api import client_for

pytestmark = pytest.mark.django_db

NOW = datetime(2026, 6, 1, 12, tzinfo=UTC)


def recording(drone, days_ago: float, size: int) -> VideoRecording:  # type: ignore[no-untyped-def]
    start = NOW - timedelta(days=days_ago)
    row = VideoRecording(drone=drone, started_at=start, ended_at=start + timedelta(minutes=5),
                         size=size, frames=10, width=320, height=240)  # fmt: skip
    row.file.save(f"test-{drone.drone_id}-{days_ago}.webm", ContentFile(b"x" * size), save=False)
    row.save()
    return row


def test_old_recordings_go_and_each_organisation_keeps_its_newest_within_its_cap(world, settings):  # type: ignore[no-untyped-def]
    settings.LIVE_VIDEO_RECORDING_KEEP_DAYS = 30
    settings.LIVE_VIDEO_RECORDINGS_MAX_BYTES_PER_ORG = 250
    expired = recording(world.drone, 31, 10)
    oldest, older, newest = (recording(world.drone, d, 100) for d in (3, 2, 1))
    theirs = recording(world.other_drone, 5, 200)
    assert prune(NOW) == 2
    kept = set(VideoRecording.objects.values_list("pk", flat=True))
    assert kept == {older.pk, newest.pk, theirs.pk}
    for gone in (expired, oldest):
        assert not gone.file.storage.exists(gone.file.name)
    assert prune(NOW) == 0


def test_an_organisations_own_period_and_cap_replace_the_platforms_for_it_alone(world, settings):  # type: ignore[no-untyped-def]
    settings.LIVE_VIDEO_RECORDING_KEEP_DAYS = 30
    settings.LIVE_VIDEO_RECORDINGS_MAX_BYTES_PER_ORG = 10_000
    set_rule(world.org, {"keep_days": 7, "max_bytes": 2 << 20})
    week_old = recording(world.drone, 8, 10)
    big_old, big_new = (recording(world.drone, d, 1 << 20) for d in (3, 2))
    small_new = recording(world.drone, 1, 1000)
    theirs = recording(world.other_drone, 8, 10)  # the platform's 30 days hold for them
    assert prune(NOW) == 2
    kept = set(VideoRecording.objects.values_list("pk", flat=True))
    assert kept == {big_new.pk, small_new.pk, theirs.pk}
    assert not week_old.file.storage.exists(week_old.file.name)
    assert not big_old.file.storage.exists(big_old.file.name)
    # Back to the platform's setting: null.
    body = set_rule(world.org, {"keep_days": None, "max_bytes": None})
    assert body["keep_days"] == 30 and body["max_bytes"] == 10_000 and not body["own_rule"]


def test_admins_set_the_rule_members_read_it_and_others_never_reach_it(world):  # type: ignore[no-untyped-def]
    url = f"/api/v1/organisations/{world.org.slug}/video-retention/"
    reader = client_for(world.viewer)
    assert reader.get(url).json()["own_rule"] is False
    assert reader.put(url, {"keep_days": 3}, content_type="application/json").status_code == 403
    admin = client_for(world.owner)
    answer = admin.put(url, {"keep_days": 3, "max_bytes": 1 << 30}, content_type="application/json")
    assert answer.status_code == 200, answer.content
    assert answer.json()["keep_days"] == 3 and answer.json()["own_rule"] is True
    assert reader.get(url).json()["max_bytes"] == 1 << 30
    for bad in ({"keep_days": 0}, {"max_bytes": 5}, {"keep_days": "7"}, {"colour": 1}):
        refused = admin.put(url, bad, content_type="application/json")
        assert refused.status_code == 400, bad
    assert VideoRetention.objects.get(organisation=world.org).keep_days == 3  # unchanged
    theirs = f"/api/v1/organisations/{world.other_org.slug}/video-retention/"
    assert admin.get(theirs).status_code == 404
    assert admin.put(theirs, {"keep_days": 1}, content_type="application/json").status_code == 404
    assert client_for(world.outsider).get(url).status_code == 404
