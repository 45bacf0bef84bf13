import zipfile

import numpy as np
import pytest

from logs import LogFormatError, find_special, import_log
from logs.importers.base import Limits
from tests.logs.dfi_builder import DESCRIPTION, write_dfi


def test_hand_made_dfi_gives_one_layer_per_value_file(tmp_path):
    log = import_log(write_dfi(tmp_path / "flight.dfi"))
    assert log.layers == ["navdata", "commands"]
    alt = log.series["navdata/Altitude"]
    assert alt.unit == "m"
    np.testing.assert_array_equal(alt.values, [0.5, 0.75, 1.25])
    # The board clock is the more precise one, so it stamps the layer.
    assert alt.time_source == "board"
    np.testing.assert_array_equal(alt.times, [1_000_000, 2_000_000, 3_000_000])
    recorder = log.series["navdata/time (recorder)"]
    np.testing.assert_array_equal(recorder.values, [5_000_000, 6_000_000, 7_000_000])
    cmd = log.series["commands/Velocity/z"]
    assert cmd.time_source == "recorder"
    np.testing.assert_array_equal(cmd.times, [5_000_000, 6_000_000])
    np.testing.assert_array_equal(cmd.values, [-0.2, 0.0])


def test_dfi_keeps_integer_enumerations_with_their_labels(tmp_path):
    log = import_log(write_dfi(tmp_path / "flight.zip"))
    state = log.series["navdata/state"]
    assert state.kind == "enum"
    assert state.values.dtype == np.int64
    np.testing.assert_array_equal(state.values, [2, 3, 3])
    assert state.labels == {2: "Landed", 3: "Flying"}
    assert log.series["navdata/Motor powers/motor 2"].values.tolist() == [101, 121, 141]


def test_dfi_special_quantities_are_found_by_name(tmp_path):
    special = find_special(import_log(write_dfi(tmp_path / "flight.dfi")))
    assert special["altitude"] == ["navdata/Altitude"]
    assert special["rotation"] == [
        "navdata/Rotation/roll",
        "navdata/Rotation/pitch",
        "navdata/Rotation/yaw",
    ]
    assert special["motors"] == ["navdata/Motor powers/motor 1", "navdata/Motor powers/motor 2"]
    assert special["velocity"] == [
        "commands/Velocity/x",
        "commands/Velocity/y",
        "commands/Velocity/z",
    ]


def _rejects(tmp_path, match, files=None, description=DESCRIPTION, **kw):
    path = write_dfi(tmp_path / "bad.dfi", files, description)
    with pytest.raises(LogFormatError, match=match):
        import_log(path, **kw)


def test_dfi_without_description_is_rejected(tmp_path):
    _rejects(tmp_path, "no description.xml", {"description.xml": None, "other.txt": "x"})


def test_dfi_naming_a_missing_file_is_rejected(tmp_path):
    _rejects(
        tmp_path, "'cmd/commands.tsv', which is not in the archive", {"cmd/commands.tsv": None}
    )


def test_dfi_row_with_wrong_column_count_is_rejected(tmp_path):
    _rejects(
        tmp_path,
        r"navdata.csv, line 2: 8 values where description.xml describes 9",
        {"navdata.csv": "1,5,0.5,1,2,3,4,5,2\n2,6,0.5,1,2,3,4,5\n"},
    )


def test_dfi_value_not_of_its_declared_type_is_rejected(tmp_path):
    _rejects(
        tmp_path,
        r"line 1: value '4.5' of column 'Motor powers/motor 1' is not an integer",
        {"navdata.csv": "1,5,0.5,1,2,3,4.5,5,2\n"},
    )
    _rejects(
        tmp_path,
        r"value 'high' of column 'Altitude' is not a floating-point number",
        {"navdata.csv": "1,5,high,1,2,3,4,5,2\n"},
    )


def test_dfi_time_that_is_not_an_integer_is_rejected(tmp_path):
    _rejects(tmp_path, "is not an integer", {"navdata.csv": "1.5,5,0.5,1,2,3,4,5,2\n"})


def test_dfi_unknown_separator_is_rejected(tmp_path):
    _rejects(
        tmp_path,
        "unknown separator 'semicolon'",
        description=DESCRIPTION.replace('separator="tab"', 'separator="semicolon"'),
    )


def test_dfi_unknown_time_unit_is_rejected(tmp_path):
    _rejects(
        tmp_path,
        "unknown time unit 'fortnights'",
        description=DESCRIPTION.replace(
            'unit="milliseconds" source="recorder"/>\n    <group',
            'unit="fortnights" source="recorder"/>\n    <group',
        ),
    )


def test_dfi_unknown_time_source_is_rejected(tmp_path):
    _rejects(
        tmp_path,
        "unknown time source 'satellite'",
        description=DESCRIPTION.replace('source="board"', 'source="satellite"'),
    )


def test_dfi_separator_that_does_not_match_the_file_is_rejected(tmp_path):
    _rejects(
        tmp_path,
        "separator attribute",
        description=DESCRIPTION.replace('separator="comma"', 'separator="tab"'),
    )


def test_dfi_empty_value_between_separators_is_rejected(tmp_path):
    _rejects(tmp_path, "line 1: empty value in column 3", {"navdata.csv": "1,5,,1,2,3,4,5,2\n"})


def test_dfi_two_groups_naming_one_file_are_rejected(tmp_path):
    doubled = DESCRIPTION.replace('file="cmd/commands.tsv"', 'file="navdata.csv"').replace(
        'separator="tab"', 'separator="comma"'
    )
    _rejects(tmp_path, "two toplevelgroups name the same file", description=doubled)


def test_dfi_group_without_time_is_rejected(tmp_path):
    _rejects(
        tmp_path,
        "'commands' has no <time> child",
        description=DESCRIPTION.replace(
            '<time unit="milliseconds" source="recorder"/>\n    <group name="Velocity">',
            '<group name="Velocity">',
        ),
        files={"cmd/commands.tsv": "0.1\t0.0\t-0.2\n"},
    )


def test_dfi_with_wrong_document_element_is_rejected(tmp_path):
    _rejects(tmp_path, "not <recording>", description=DESCRIPTION.replace("recording>", "flight>"))


def test_dfi_with_entity_expansion_is_refused(tmp_path):
    bomb = (
        '<?xml version="1.0"?>\n<!DOCTYPE recording [\n <!ENTITY a "aaaaaaaaaa">\n'
        ' <!ENTITY b "&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;">\n <!ENTITY c "&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;">\n]>\n'
        '<recording><toplevelgroup name="&c;" file="navdata.csv" separator="comma"/></recording>'
    )
    _rejects(tmp_path, "DTD or entities, which are refused", description=bomb)


def test_zip_bomb_is_refused_before_unpacking(tmp_path):
    path = tmp_path / "bomb.dfi"
    write_dfi(path)
    with zipfile.ZipFile(path, "a", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("padding.bin", b"\0" * (50 << 20))
    with pytest.raises(LogFormatError, match="compressed .*:1, over the limit"):
        import_log(path)
    with pytest.raises(LogFormatError, match="would unpack to .* bytes, over the limit"):
        import_log(path, limits=Limits(max_uncompressed_bytes=10 << 20))


def test_archive_with_too_many_members_is_refused(tmp_path):
    _rejects(
        tmp_path,
        "members, over the limit of 5",
        {f"junk{i}.txt": "x" for i in range(10)},
        limits=Limits(max_members=5),
    )


def test_truncated_dfi_is_rejected(tmp_path):
    path = write_dfi(tmp_path / "flight.dfi")
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(LogFormatError, match="not a ZIP archive .*truncated"):
        import_log(path)


def test_malformed_xml_is_rejected(tmp_path):
    _rejects(tmp_path, "not well-formed XML", description="<recording><toplevelgroup>")


def test_dfi_value_files_are_read_in_chunks_with_true_line_numbers(tmp_path, monkeypatch):
    from logs.importers import dfi

    monkeypatch.setattr(dfi, "CHUNK_LINES", 2)
    log = import_log(write_dfi(tmp_path / "flight.dfi"))
    np.testing.assert_array_equal(log.series["navdata/Altitude"].values, [0.5, 0.75, 1.25])
    rows = "1,5,0.5,1,2,3,4,5,2\r\n2,6,0.5,1,2,3,4,5,2\r\n3,7,x,1,2,3,4,5,2\r\n"
    _rejects(tmp_path, "line 3: value 'x'", {"navdata.csv": rows})


def test_dfi_blank_line_between_rows_is_rejected_but_trailing_ones_are_not(tmp_path):
    _rejects(
        tmp_path,
        "line 2: empty line between rows",
        {"navdata.csv": "1,5,0.5,1,2,3,4,5,2\n\n2,6,0.5,1,2,3,4,5,2\n"},
    )
    log = import_log(write_dfi(tmp_path / "ok.dfi", {"navdata.csv": "1,5,0.5,1,2,3,4,5,2\n\n\n"}))
    assert len(log.series["navdata/Altitude"].values) == 1
