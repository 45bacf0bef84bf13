"""The vectorised ULog reader against pyulog, the parser PX4 Flight Review uses: the same
topics, fields, types and values on real logs, on files pyulog itself writes, across chunk
boundaries, and on cut or damaged files."""

from pathlib import Path

import numpy as np
import pytest
from pyulog import ULog

from logs.importers import ulog_reader
from logs.importers.ulog_reader import UlogError, read_ulog
from logs.synth import synthetic_ulog
from tests.support.paths import REAL_ULOGS

REAL_LOGS = sorted(REAL_ULOGS.glob("*.ulg"))


def _datasets(log) -> dict[tuple[str, int], dict[str, np.ndarray]]:
    return {(d.name, d.multi_id): d.data for d in log.data_list}


def _assert_same(ours, theirs) -> None:
    assert ours.start_timestamp == theirs.start_timestamp
    assert ours.msg_info_dict == theirs.msg_info_dict
    assert ours.initial_parameters == theirs.initial_parameters
    assert [(m.timestamp, m.log_level, m.message) for m in ours.logged_messages] == [
        (m.timestamp, m.log_level, m.message) for m in theirs.logged_messages
    ]
    a, b = _datasets(ours), _datasets(theirs)
    assert list(a) == list(b)
    for key, fields in b.items():
        assert list(a[key]) == list(fields), key
        for name, values in fields.items():
            assert a[key][name].dtype == values.dtype, (key, name)
            np.testing.assert_array_equal(a[key][name], values, err_msg=f"{key} {name}")


@pytest.mark.parametrize("path", REAL_LOGS, ids=lambda p: p.name)
def test_real_px4_logs_read_exactly_as_pyulog_reads_them(path):
    ours = read_ulog(path)
    _assert_same(ours, ULog(str(path)))
    assert not ours.file_corruption


@pytest.mark.parametrize("path", REAL_LOGS, ids=lambda p: p.name)
def test_a_log_written_by_pyulog_reads_the_same(path, tmp_path):
    rewritten = tmp_path / "rewritten.ulg"
    ULog(str(path)).write_ulog(str(rewritten))
    _assert_same(read_ulog(rewritten), ULog(str(rewritten)))


@pytest.mark.parametrize("chunk", [64, 1000, 4096])
def test_messages_split_across_chunks_are_read_whole(monkeypatch, chunk):
    monkeypatch.setattr(ulog_reader, "CHUNK_BYTES", chunk)
    for path in REAL_LOGS:
        _assert_same(read_ulog(path), ULog(str(path)))


@pytest.mark.parametrize("block", [1, 7, 1 << 20])
def test_record_starts_kept_across_many_blocks_fill_every_topic_in_order(monkeypatch, block):
    """Starts split over many blocks, or one chunk's starts longer than a block (kept on
    their own): the second pass still fills each topic in file order."""
    monkeypatch.setattr(ulog_reader, "CHUNK_BYTES", 4096)
    monkeypatch.setattr(ulog_reader, "STARTS_BLOCK", block)
    monkeypatch.setattr(ulog_reader, "COPY_BLOCK", 5)
    for path in REAL_LOGS:
        _assert_same(read_ulog(path), ULog(str(path)))


def test_a_log_cut_in_the_middle_of_a_message_keeps_every_whole_message(tmp_path):
    source = tmp_path / "full.ulg"
    synthetic_ulog(source, seconds=2)
    raw = source.read_bytes()
    cut = tmp_path / "cut.ulg"
    cut.write_bytes(raw[: len(raw) * 2 // 3 + 7])
    _assert_same(read_ulog(cut), ULog(str(cut)))


def test_garbage_in_the_middle_is_skipped_and_flagged(tmp_path):
    source = tmp_path / "full.ulg"
    synthetic_ulog(source, seconds=2)
    raw = source.read_bytes()
    middle = len(raw) // 2
    damaged = tmp_path / "damaged.ulg"
    damaged.write_bytes(raw[:middle] + bytes(64) + raw[middle:])
    ours, theirs = read_ulog(damaged), ULog(str(damaged))
    assert ours.file_corruption and theirs.file_corruption
    before = read_ulog(_cut(source, tmp_path, middle))
    recovered = _datasets(ours)
    for key, fields in _datasets(theirs).items():
        # The same recovery as pyulog's, keeping at least everything before the damage.
        assert len(recovered[key]["timestamp"]) == len(fields["timestamp"])
        assert len(fields["timestamp"]) >= len(_datasets(before)[key]["timestamp"])


def _cut(source: Path, tmp_path: Path, size: int) -> Path:
    path = tmp_path / "head.ulg"
    path.write_bytes(source.read_bytes()[:size])
    return path


@pytest.mark.parametrize("size", [0, 1])
def test_a_data_message_too_short_for_its_id_is_skipped_and_flagged(tmp_path, size):
    """At the very end of the file its id would lie past the last byte."""
    source = REAL_LOGS[0]
    short = tmp_path / "short.ulg"
    short.write_bytes(source.read_bytes() + bytes([size, 0, ord("D")]) + b"\x07" * size)
    ours = read_ulog(short)
    assert ours.file_corruption
    a, b = _datasets(ours), _datasets(read_ulog(source))
    assert list(a) == list(b)
    for key, fields in b.items():
        for name, values in fields.items():
            np.testing.assert_array_equal(a[key][name], values, err_msg=f"{key} {name}")


def test_a_file_that_is_not_a_ulog_is_refused(tmp_path):
    path = tmp_path / "not.ulg"
    path.write_bytes(b"PK\x03\x04" + bytes(100))
    with pytest.raises(UlogError, match="magic"):
        read_ulog(path)
    path.write_bytes(b"ULog\x01")
    with pytest.raises(UlogError, match="too short"):
        read_ulog(path)


def test_unknown_incompatible_flags_are_refused(tmp_path):
    path = Path(tmp_path / "flags.ulg")
    source = REAL_LOGS[0].read_bytes()
    assert source[16 + 2] == ord("B")
    flagged = bytearray(source)
    flagged[16 + 3 + 8] |= 0x02  # an incompatible flag bit nobody defined
    path.write_bytes(bytes(flagged))
    with pytest.raises(UlogError, match="incompatible"):
        read_ulog(path)
