"""The agent's log collection on its own: the operator's setting and the uplink type read
from the gear folder, and the upload's pace."""

from __future__ import annotations

import json

import pytest

from onboard.collect import TokenBucket, read_policy


@pytest.mark.parametrize(
    ("collect", "uplink_file", "flag", "queued", "sent"),
    [
        (None, None, "cellular", True, True),  # no setting: always
        ("always", None, "cellular", True, True),
        ("ground_links", None, "cellular", True, False),  # kept until a ground link
        ("ground_links", None, "wifi", True, True),
        ("ground_links", "ground", "cellular", True, True),  # the gear file wins
        ("ground_links", "radio", "wifi", True, False),
        ("off", "wifi", "wifi", False, False),
        ("sometimes", None, "radio", True, True),  # unknown: the default, always
    ],
)
def test_the_gear_folder_says_whether_and_when_logs_go(
    tmp_path, collect, uplink_file, flag, queued, sent
):
    if collect is not None:
        (tmp_path / "collect.json").write_text(json.dumps({"collect": collect}))
    if uplink_file is not None:
        (tmp_path / "uplink.json").write_text(json.dumps({"type": uplink_file}))
    policy = read_policy(tmp_path, flag)
    assert (policy.queue, policy.send_now) == (queued, sent)


def test_a_broken_setting_file_counts_as_the_default(tmp_path):
    (tmp_path / "collect.json").write_text("{not json")
    assert read_policy(tmp_path, "cellular").send_now
    assert read_policy(None, "unknown").queue


def test_the_upload_keeps_to_its_rate():
    now = [0.0]
    bucket = TokenBucket(rate=1000.0, burst=1000.0, clock=lambda: now[0])
    assert bucket.wait_time(1000) == 0.0  # a full bucket: the first chunk goes at once
    assert bucket.wait_time(500) == pytest.approx(0.5)
    now[0] = 0.5
    assert bucket.wait_time(500) == 0.0
    sent, t = 0, 0.5
    while t < 10.5:  # ten seconds of chunks as fast as the bucket lets them go
        wait = bucket.wait_time(250)
        if wait:
            t += wait
            now[0] = t
            continue
        sent += 250
    assert 1000 * 10 - 250 <= sent <= 1000 * 10 + 250
