import json

import numpy as np
import pytest

from logs import LogFormatError, find_special, import_log


def mission_log(**extra):
    events = []
    for i in range(5):
        for drone, lat in (("d1", 50.0), ("d2", 51.0)):
            events.append(
                {
                    "ts": f"2026-11-22T10:00:{i * 2 + (drone == 'd2'):02d}Z",
                    "drone_id": drone,
                    "type": "step_done" if i else "takeoff",
                    "index": i,
                    "status": "done",
                    "position": {"lat": lat + i * 1e-4, "lon": 14.0, "alt": 10.0 + i},
                    "duration_s": 1.5,
                    "battery": 90 - i,  # an extra field: ignored, not an error
                }
            )
    # Unix seconds work as well as ISO strings.
    events.append({"ts": 1795341660.5, "drone_id": "d1", "type": "landed", "status": "done"})
    doc = {
        "mission": {"id": 7, "name": "Survey"},
        "drones": [{"id": "d1", "name": "Alpha"}, {"id": "d2", "name": "Bravo"}],
        "assignments": [{"drone_id": "d1", "steps": [0, 1, 2]}],
        "events": events,
        **extra,
    }
    return json.dumps(doc)


def test_mission_log_gives_one_layer_per_drone(tmp_path):
    path = tmp_path / "mission.json"
    path.write_text(mission_log())
    log = import_log(path)
    assert log.layers == ["drone Alpha", "drone Bravo"]
    lat = log.series["drone Bravo/lat"]
    np.testing.assert_allclose(lat.values, 51.0 + np.arange(5) * 1e-4)
    assert lat.unit == "deg" and lat.time_source == "recorder"
    assert lat.times[1] - lat.times[0] == 2 * 10**9
    assert log.series["drone Alpha/step index"].values.tolist() == [0, 1, 2, 3, 4]
    event = log.series["drone Alpha/event"]
    assert [event.labels[v] for v in event.values.tolist()] == ["takeoff"] + ["step_done"] * 4 + [
        "landed"
    ]
    assert log.metadata["mission"] == {"id": 7, "name": "Survey"}
    assert find_special(log)["gps"] == ["drone Alpha/lat", "drone Alpha/lon", "drone Alpha/alt"]
    by_layer = log.special_by_layer()
    assert by_layer["drone Bravo"]["gps"] == [
        "drone Bravo/lat",
        "drone Bravo/lon",
        "drone Bravo/alt",
    ]
    assert find_special(log, layer="drone Bravo") == by_layer["drone Bravo"]


def test_mission_log_skips_events_it_cannot_place_and_says_so(tmp_path):
    path = tmp_path / "mission.json"
    doc = json.loads(mission_log())
    doc["events"] += [{"ts": "yesterday", "drone_id": "d1"}, {"ts": 1.0}, "not an event"]
    path.write_text(json.dumps(doc))
    log = import_log(path)
    assert log.warnings == ["Skipped 3 events without a drone or a readable time."]


def test_truncated_mission_log_is_rejected(tmp_path):
    path = tmp_path / "mission.json"
    path.write_text(mission_log()[:300])
    with pytest.raises(LogFormatError, match="not valid JSON"):
        import_log(path)


def test_json_without_events_is_rejected(tmp_path):
    path = tmp_path / "other.json"
    path.write_text('{"mission": {}}')
    with pytest.raises(LogFormatError, match='no "events" list'):
        import_log(path)
