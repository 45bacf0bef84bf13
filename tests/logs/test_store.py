import json

import numpy as np
import pytest

from logs import LogFormatError, import_log
from logs.series import LogData, Series
from logs.store import import_to_store, open_store, write_store
from tests.logs.dfi_builder import write_dfi


def _log() -> LogData:
    log = LogData(format="test")
    t = np.arange(0, 10_000, dtype=np.int64) * 10_000_000  # 100 Hz for 100 s
    log.add(
        Series("imu/acc/x", np.sin(np.arange(10_000) / 50.0), t, unit="m/s2", time_source="board")
    )
    log.add(
        Series("imu/acc/y", np.cos(np.arange(10_000) / 50.0), t, unit="m/s2", time_source="board")
    )
    log.add(
        Series(
            "state/mode",
            np.array([1, 2, 1]),
            np.array([0, 5, 9], dtype=np.int64) * 1_000_000_000,
            kind="enum",
            labels={1: "hover", 2: "climb"},
        )
    )
    log.add(
        Series(
            "state/text",
            np.array(["a", "bb", "ccc"]),
            np.array([0, 5, 9], dtype=np.int64) * 1_000_000_000,
            kind="text",
        )
    )
    return log


def test_store_round_trip_keeps_every_value_unit_and_label(tmp_path):
    log = _log()
    write_store(log, tmp_path / "log1")
    store = open_store(tmp_path / "log1")
    assert store.paths == list(log.series)
    for s in log:
        t, v = store.read_ns(s.path)
        np.testing.assert_array_equal(t, s.times)
        np.testing.assert_array_equal(v, s.values)
    info = store.info("state/mode")
    assert info["labels"] == {"1": "hover", "2": "climb"}
    assert info["count"] == 3 and info["start"] == 0.0 and info["end"] == 9.0
    assert store.info("imu/acc/x")["unit"] == "m/s2"
    assert [layer["name"] for layer in store.index["layers"]] == ["imu", "state"]
    # Fields of one message share one time file.
    assert store.info("imu/acc/x")["times"] == store.info("imu/acc/y")["times"]


def test_store_reads_a_time_range_memory_mapped(tmp_path):
    write_store(_log(), tmp_path / "log1")
    store = open_store(tmp_path / "log1")
    t, v = store.read("imu/acc/x", start=10.0, end=10.5)
    np.testing.assert_allclose(t, np.arange(1000, 1051) / 100)
    np.testing.assert_allclose(v, np.sin(np.arange(1000, 1051) / 50.0))
    raw_t, _ = store.read_ns("imu/acc/x", 10 * 10**9, None)
    assert isinstance(raw_t.base, np.memmap) or isinstance(raw_t, np.memmap)


def test_store_plot_downsamples_for_the_api(tmp_path):
    write_store(_log(), tmp_path / "log1")
    store = open_store(tmp_path / "log1")
    body = store.plot("imu/acc/x", points=100)
    assert len(body["t"]) <= 200 and max(body["v"]) == pytest.approx(1.0, abs=1e-3)
    everything = store.plot("imu/acc/x", start=0.0, end=0.05)
    assert everything == {
        "t": [0.0, 0.01, 0.02, 0.03, 0.04, 0.05],
        "v": np.sin(np.arange(6) / 50.0).tolist(),
    }
    assert store.plot("state/text")["v"] == ["a", "bb", "ccc"]


def test_store_index_lists_special_quantities_of_the_log(tmp_path):
    write_store(import_log(write_dfi(tmp_path / "f.dfi")), tmp_path / "log2")
    index = json.loads((tmp_path / "log2" / "index.json").read_text())
    assert index["special"]["altitude"] == ["navdata/Altitude"]
    assert index["special_by_layer"]["commands"] == {
        "velocity": ["commands/Velocity/x", "commands/Velocity/y", "commands/Velocity/z"]
    }
    assert index["format"] == "dfi"


def test_failed_write_leaves_nothing_behind_and_keeps_the_old_store(tmp_path):
    write_store(_log(), tmp_path / "log1")
    bad = _log()
    bad.add(Series("bad/object", np.array([object()], dtype=object), np.array([0], dtype=np.int64)))
    with pytest.raises(ValueError):
        write_store(bad, tmp_path / "log1")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["log1"]
    assert open_store(tmp_path / "log1").paths == list(_log().series)


def test_rewriting_a_store_replaces_it(tmp_path):
    write_store(_log(), tmp_path / "log1")
    write_store(import_log(write_dfi(tmp_path / "f.dfi")), tmp_path / "log1")
    assert open_store(tmp_path / "log1").index["format"] == "dfi"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f.dfi", "log1"]


def test_import_to_store_reports_progress_and_summarises_series(tmp_path):
    seen = []
    store = import_to_store(write_dfi(tmp_path / "f.dfi"), tmp_path / "s", progress=seen.append)
    assert seen[-1] == 1.0 and seen == sorted(seen)
    assert store.series_list()[0] == {
        "path": "navdata/time (recorder)",
        "unit": "ns",
        "count": 3,
        "start": 0.001,
        "end": 0.003,
    }
    assert {
        "path": "commands/Velocity/x",
        "unit": "m/s",
        "count": 2,
        "start": 0.005,
        "end": 0.006,
    } in store.series_list()


def test_import_to_store_writes_nothing_for_a_bad_file(tmp_path):
    bad = tmp_path / "bad.ulg"
    bad.write_bytes(b"ULog\x01\x12\x35\x01" + b"\0" * 3)
    with pytest.raises(LogFormatError):
        import_to_store(bad, tmp_path / "s")
    assert not (tmp_path / "s").exists()
