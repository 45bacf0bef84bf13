"""A PX4 ULog imported the way the import task does it (import_to_store), which writes each
block of records to the store as the reader hands it over: the same store as the whole log
parsed in memory and then written, memory that does not grow with the log, and the same
refusals."""

import subprocess
import sys
import tracemalloc
from pathlib import Path

import numpy as np
import pytest

from logs import LogFormatError, import_log
from logs.importers import ulog_reader
from logs.store import import_to_store, open_store, write_store
from logs.synth import synthetic_ulog, write_ulog
from tests.logs.test_corrupt_input import damaged_copies
from tests.support.paths import REAL_ULOGS

REAL_LOGS = sorted(REAL_ULOGS.glob("*.ulg"))
assert len(REAL_LOGS) == 2, f"expected the two PX4 logs in {REAL_ULOGS}"


def _assert_same_store(streamed: Path, whole: Path) -> None:
    a, b = open_store(streamed), open_store(whole)
    index_a, index_b = dict(a.index), dict(b.index)
    series_a, series_b = index_a.pop("series"), index_b.pop("series")
    assert index_a == index_b
    assert list(series_a) == list(series_b)
    for path, info in series_b.items():
        names = ("times", "values")
        assert {k: v for k, v in series_a[path].items() if k not in names} == {
            k: v for k, v in info.items() if k not in names
        }, path
        (t_a, v_a), (t_b, v_b) = a.read_ns(path), b.read_ns(path)
        assert (t_a.dtype, v_a.dtype) == (t_b.dtype, v_b.dtype), path
        np.testing.assert_array_equal(t_a, t_b, err_msg=path)
        np.testing.assert_array_equal(v_a, v_b, err_msg=path)


def _synthetic(tmp_path: Path, seconds: float) -> Path:
    path = tmp_path / "synthetic.ulg"
    synthetic_ulog(path, seconds=seconds)
    return path


@pytest.mark.parametrize("name", [p.name for p in REAL_LOGS] + ["synthetic"])
def test_a_streamed_ulog_store_is_the_store_of_the_log_read_whole(tmp_path, name, monkeypatch):
    # Small chunks and blocks: records of one topic cross many of both.
    monkeypatch.setattr(ulog_reader, "CHUNK_BYTES", 4096)
    monkeypatch.setattr(ulog_reader, "COPY_BLOCK", 7)
    path = _synthetic(tmp_path, 20) if name == "synthetic" else REAL_ULOGS / name
    import_to_store(path, tmp_path / "streamed")
    write_store(import_log(path), tmp_path / "whole")
    _assert_same_store(tmp_path / "streamed", tmp_path / "whole")
    # The streamed store's columns are referred to, not written twice.
    files = {p.name for p in (tmp_path / "streamed").iterdir()} - {"index.json"}
    index = open_store(tmp_path / "streamed").index["series"]
    assert files == {i[k] for i in index.values() for k in ("times", "values")}


def test_attitude_angles_are_streamed_with_their_topic(tmp_path):
    store = import_to_store(_synthetic(tmp_path, 5), tmp_path / "s")
    assert store.special["rotation"] == [
        "vehicle_attitude/euler/roll",
        "vehicle_attitude/euler/pitch",
        "vehicle_attitude/euler/yaw",
    ]
    _, yaw = store.read_ns("vehicle_attitude/euler/yaw")
    t_q, _ = store.read_ns("vehicle_attitude/q[0]")
    assert yaw.dtype == np.float32 and len(yaw) == len(t_q) == 5 * 250


def test_import_to_store_holds_blocks_not_the_log(tmp_path, monkeypatch):
    """What the import keeps at its peak is a small part of the file: the whole log parsed
    in memory holds about the file's size (which the same measure shows)."""
    monkeypatch.setattr(ulog_reader, "CHUNK_BYTES", 1 << 20)
    monkeypatch.setattr(ulog_reader, "STARTS_BLOCK", 1 << 16)
    monkeypatch.setattr(ulog_reader, "COPY_BLOCK", 1 << 12)
    path = _synthetic(tmp_path, 1000)
    size = path.stat().st_size
    assert size > 20 << 20

    def peak(run) -> int:
        tracemalloc.start()
        try:
            run()
            return tracemalloc.get_traced_memory()[1]
        finally:
            tracemalloc.stop()

    streamed = peak(lambda: import_to_store(path, tmp_path / "s"))
    whole = peak(lambda: import_log(path))
    assert whole > 0.8 * size
    # Record starts (4 bytes a message, about a tenth of it), one chunk and one block.
    assert streamed < 0.25 * size, (streamed, size)


def test_import_to_store_reports_ulog_progress_as_it_reads(tmp_path, monkeypatch):
    monkeypatch.setattr(ulog_reader, "CHUNK_BYTES", 64 << 10)
    seen: list[float] = []
    import_to_store(_synthetic(tmp_path, 20), tmp_path / "s", progress=seen.append)
    assert seen == sorted(seen) and seen[-1] == 1.0
    assert len({round(f, 2) for f in seen if f < 0.9}) > 10


def _bad_timestamp_log(path: Path) -> Path:
    good = np.zeros(50, dtype=[("timestamp", "<u8"), ("x", "<f4")])
    good["timestamp"] = np.arange(50) * 1000
    bad = np.zeros(50, dtype=[("timestamp", "<u4"), ("y", "<f4")])
    bad["timestamp"] = np.arange(50) * 1000
    write_ulog(path, {"a_good": good, "b_bad": bad})
    return path


def test_a_ulog_refused_while_streaming_leaves_nothing_and_says_why(tmp_path):
    path = _bad_timestamp_log(tmp_path / "bad.ulg")
    with pytest.raises(LogFormatError, match="timestamp") as streamed:
        import_to_store(path, tmp_path / "s")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.ulg"]
    with pytest.raises(LogFormatError) as whole:
        import_log(path)
    assert str(streamed.value) == str(whole.value)


_WRITE_FAILS = """
import resource, signal, sys
from pathlib import Path
from logs import LogFormatError
from logs.importers.base import StoreWriteError
from logs.store import import_to_store
# Files past 64 KiB cannot be written: the store's largest columns fail, as on a full disk.
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
resource.setrlimit(resource.RLIMIT_FSIZE, (64 << 10, 64 << 10))
try:
    import_to_store(Path(sys.argv[1]), Path(sys.argv[2]))
except StoreWriteError as exc:
    print("StoreWriteError", exc)
except LogFormatError as exc:
    print("LogFormatError", exc)
"""


def test_a_store_that_cannot_be_written_is_not_blamed_on_the_log(tmp_path):
    path = _synthetic(tmp_path, 60)  # the file itself is larger than the limit: read only
    out = subprocess.run(
        [sys.executable, "-c", _WRITE_FAILS, str(path), str(tmp_path / "s")],
        capture_output=True,
        text=True,
        timeout=120,
        check=True,
    ).stdout
    assert out.startswith("StoreWriteError"), out
    assert sorted(p.name for p in tmp_path.iterdir()) == ["synthetic.ulg"]


@pytest.mark.parametrize("tail", [b"", b"\x05", b"\x05\x00", b"\x05\x00D", b"\x05\x00D\x01\x00"])
def test_the_walk_stops_at_the_first_message_the_buffer_does_not_hold_whole(tail):
    messages = b"".join(bytes([n, 0, ord("D")]) + bytes(n) for n in (0, 2, 7, 1))
    offsets, stop = ulog_reader._walk(messages + tail)
    assert offsets.tolist() == [0, 3, 8, 18]
    assert stop == len(messages)
    assert ulog_reader._walk(b"")[1] == 0


def test_damaged_ulogs_are_stored_or_refused_alike_streamed_and_whole(tmp_path):
    original = _synthetic(tmp_path, 2).read_bytes()
    rng = np.random.default_rng(11)
    outcomes = {"stored": 0, "refused": 0}
    for trial, data in enumerate(damaged_copies(original, rng)):
        path = tmp_path / f"bad{trial}.ulg"
        path.write_bytes(data)
        streamed, whole = tmp_path / f"streamed{trial}", tmp_path / f"whole{trial}"
        try:
            log = import_log(path)
        except LogFormatError as exc:
            with pytest.raises(LogFormatError) as refused:
                import_to_store(path, streamed)
            assert str(refused.value) == str(exc)
            assert not streamed.exists()
            outcomes["refused"] += 1
            continue
        write_store(log, whole)
        import_to_store(path, streamed)
        _assert_same_store(streamed, whole)
        outcomes["stored"] += 1
    assert outcomes["stored"] and outcomes["refused"], outcomes
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]
