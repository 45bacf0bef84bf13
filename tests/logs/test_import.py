import pytest

from logs import LogFormatError, import_log
from logs.importers.base import Limits
from logs.synth import synthetic_dataflash, synthetic_ulog
from tests.logs.dfi_builder import write_dfi


def test_format_is_picked_by_content_before_extension(tmp_path):
    ulog = tmp_path / "really-a-ulog.bin"
    synthetic_ulog(ulog, seconds=1)
    assert import_log(ulog).format == "ulog"
    dataflash = tmp_path / "really-a-bin.ulg"
    synthetic_dataflash(dataflash, seconds=1)
    assert import_log(dataflash).format == "dataflash"
    dfi = write_dfi(tmp_path / "recording.zip")
    assert import_log(dfi).format == "dfi"


def test_unknown_file_gets_a_clear_sentence(tmp_path):
    path = tmp_path / "holiday.jpg"
    path.write_bytes(b"\xff\xd8\xff\xe0 not a flight log")
    with pytest.raises(
        LogFormatError,
        match=r"'holiday.jpg' is not a flight log format we can read \(supported: .*\.ulg",
    ):
        import_log(path)


def test_wrong_extension_with_garbage_inside_is_rejected(tmp_path):
    path = tmp_path / "flight.ulg"
    path.write_bytes(b"garbage" * 100)
    with pytest.raises(LogFormatError, match="not a valid PX4 ULog"):
        import_log(path)


def test_empty_and_oversized_files_are_refused(tmp_path):
    empty = tmp_path / "empty.bin"
    empty.write_bytes(b"")
    with pytest.raises(LogFormatError, match="is empty"):
        import_log(empty)
    big = tmp_path / "big.bin"
    synthetic_dataflash(big, seconds=1)
    with pytest.raises(LogFormatError, match="over the limit of 100"):
        import_log(big, limits=Limits(max_file_bytes=100))


def test_missing_file_is_a_format_error_not_a_crash(tmp_path):
    with pytest.raises(LogFormatError, match="cannot be opened"):
        import_log(tmp_path / "nope.ulg")


def test_progress_is_reported_up_to_one(tmp_path):
    path = tmp_path / "f.bin"
    synthetic_dataflash(path, seconds=5)
    seen = []
    import_log(path, progress=seen.append)
    assert seen[-1] == 1.0
    assert seen == sorted(seen) and len(seen) > 2
