"""The ground's log collection mode on the drone: carried by the envelope message, kept
across restarts, and in force above the gear folder's collect.json."""

from __future__ import annotations

import json

import pytest

from onboard import protocol
from onboard.collect import Collector

MESSAGE = {"type": "envelope", "ts": 1767225600.0, "envelope": {}}


def collector(tmp_path, gear) -> Collector:  # type: ignore[no-untyped-def]
    return Collector(
        tmp_path / "collect",
        None,
        gear_dir=gear,
        uplink="cellular",
        policy_file=tmp_path / "collect-policy.json",
    )


@pytest.fixture
def gear(tmp_path):  # type: ignore[no-untyped-def]
    folder = tmp_path / "gear"
    folder.mkdir()
    (folder / "collect.json").write_text(json.dumps({"collect": "off"}))
    return folder


def test_without_a_word_from_the_ground_collect_json_decides(tmp_path, gear):
    assert not collector(tmp_path, gear).policy().queue


def test_the_grounds_mode_wins_over_collect_json_and_survives_a_restart(tmp_path, gear):
    first = collector(tmp_path, gear)
    first.set_mode("always")
    assert first.policy().queue and first.policy().send_now
    again = collector(tmp_path, gear)  # the agent restarted
    assert again.ground_mode.mode == "always" and again.policy().send_now
    again.set_mode("ground_links")  # cellular: queued, not sent
    assert (again.policy().queue, again.policy().send_now) == (True, False)
    (gear / "collect.json").unlink()
    again.set_mode("off")
    assert not collector(tmp_path, gear).policy().queue


def test_a_flight_ended_with_the_ground_saying_off_queues_nothing(tmp_path, gear):
    (gear / "collect.json").write_text(json.dumps({"collect": "always"}))
    drone = collector(tmp_path, gear)
    drone.set_mode("off")
    recording = tmp_path / "flight.dfi"
    recording.write_bytes(b"\x00" * 64)
    assert drone.add(recording, "onboard", 1.0, 2.0) is False
    assert drone.pending() == []


def test_a_broken_stored_mode_counts_as_none_heard(tmp_path, gear):
    (tmp_path / "collect-policy.json").write_text("{not json")
    assert collector(tmp_path, gear).ground_mode.mode is None
    (tmp_path / "collect-policy.json").write_text(json.dumps({"log_collection": "maybe"}))
    assert collector(tmp_path, gear).ground_mode.mode is None


def test_a_bad_mode_is_refused_and_the_old_one_stays(tmp_path, gear):
    drone = collector(tmp_path, gear)
    drone.set_mode("always")
    with pytest.raises(ValueError, match="log_collection"):
        drone.set_mode("sometimes")
    assert collector(tmp_path, gear).ground_mode.mode == "always"


@pytest.mark.parametrize("mode", ["always", "ground_links", "off"])
def test_the_envelope_message_carries_the_mode_both_ways(mode):
    message = protocol.EnvelopeUpdate({}, ts=1.0, log_collection=mode).to_dict()
    assert message["log_collection"] == mode
    assert protocol.parse_envelope_update(message).log_collection == mode


def test_a_message_without_the_mode_or_with_an_unknown_one_keeps_the_envelope():
    assert protocol.parse_envelope_update(MESSAGE).log_collection is None
    assert "log_collection" not in protocol.EnvelopeUpdate({}, ts=1.0).to_dict()
    unknown = {**MESSAGE, "envelope": {"max_height": 50}, "log_collection": "metered"}
    update = protocol.parse_envelope_update(unknown)
    assert update.log_collection is None and update.envelope["max_height"] == 50


def test_a_flight_with_collection_off_at_any_moment_stays_on_the_drone(tmp_path, gear):
    """The mode back on before the landing is seen does not send the flight flown off."""
    (gear / "collect.json").write_text(json.dumps({"collect": "always"}))
    drone = collector(tmp_path, gear)
    recording = tmp_path / "flight.dfi"
    recording.write_bytes(b"\x00" * 64)
    for before, during in (("off", "always"), ("always", "off")):
        drone.set_mode(before)
        drone.flight_started()
        drone.set_mode(during)
        drone.set_mode("always")
        drone.flight_ended(recording, 1.0, 2.0)
        assert list(drone.folder.glob("*.landed")) == []
    drone.flight_started()
    drone.flight_ended(recording, 3.0, 4.0)
    assert len(list(drone.folder.glob("*.landed"))) == 1
