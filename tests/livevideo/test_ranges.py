"""The byte ranges a recording's file answers (RFC 9110 §14), so a player can seek in it."""

import pytest

from livevideo.ranges import ByteRange, Unsatisfiable, parse


@pytest.mark.parametrize(
    ("header", "expected"),
    [
        ("bytes=0-99", ByteRange(0, 99)),
        ("bytes=100-", ByteRange(100, 999)),
        ("bytes=900-5000", ByteRange(900, 999)),
        ("bytes=-10", ByteRange(990, 999)),
        ("bytes=-5000", ByteRange(0, 999)),
    ],
)
def test_one_range_is_served(header, expected):  # type: ignore[no-untyped-def]
    assert parse(header, 1000) == expected


@pytest.mark.parametrize("header", [None, "", "bytes=0-1,5-9", "items=0-1", "bytes=-", "bytes=9-3"])
def test_a_list_a_foreign_unit_or_a_malformed_range_gets_the_whole_file(header):  # type: ignore[no-untyped-def]
    assert parse(header, 1000) is None


@pytest.mark.parametrize("header", ["bytes=1000-", "bytes=-0"])
def test_a_range_past_the_end_is_unsatisfiable(header):  # type: ignore[no-untyped-def]
    with pytest.raises(Unsatisfiable):
        parse(header, 1000)


def test_the_content_range_names_the_served_bytes_and_the_size():  # type: ignore[no-untyped-def]
    assert ByteRange(10, 19).content_range(1000) == "bytes 10-19/1000"
    assert ByteRange(10, 19).length == 10
