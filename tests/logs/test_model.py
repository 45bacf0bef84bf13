import numpy as np
import pytest

from logs.series import LogData, Series, find_special


def _series(path, **kw):
    return Series(path, np.zeros(2), np.array([0, 1], dtype=np.int64), **kw)


def test_group_tree_follows_the_series_paths():
    log = LogData(format="test")
    for path in ("nav/Rotation/roll", "nav/Rotation/pitch", "nav/Altitude", "cmd/Velocity/x"):
        log.add(_series(path))
    tree = log.tree()
    assert list(tree.groups) == ["nav", "cmd"]
    assert list(tree.groups["nav"].groups["Rotation"].series) == ["roll", "pitch"]
    assert list(tree.groups["nav"].series) == ["Altitude"]
    assert log.layers == ["nav", "cmd"]


def test_special_quantities_are_matched_by_dfi_names_and_flat_fields():
    log = LogData(format="test")
    for path in (
        "a/Acceleration/x",
        "a/Acceleration/y",
        "a/Acceleration/z",
        "a/Magnetometer readings/x",
        "a/Magnetometer readings/y",
        "a/Magnetometer readings/z",
        "a/Battery level",
        "a/Motor powers/motor 10",
        "a/Motor powers/motor 2",
        "b/magX",
        "b/magY",
        "b/magZ",
    ):
        log.add(_series(path))
    special = find_special(log)
    assert special["acceleration"] == ["a/Acceleration/x", "a/Acceleration/y", "a/Acceleration/z"]
    assert special["magnetometer"][0] == "a/Magnetometer readings/x"
    assert special["battery"] == ["a/Battery level"]
    assert special["motors"] == ["a/Motor powers/motor 2", "a/Motor powers/motor 10"]
    assert "gps" not in special and "rotation" not in special


def test_reader_hints_win_over_names():
    log = LogData(format="test")
    log.add(_series("x/Altitude"))
    log.add(_series("y/height", special="altitude"))
    assert find_special(log)["altitude"] == ["y/height"]


def test_series_with_mismatched_times_and_duplicate_paths_are_refused():
    with pytest.raises(ValueError):
        Series("a/b", np.zeros(3), np.zeros(2, dtype=np.int64))
    log = LogData(format="test")
    log.add(_series("a/b"))
    with pytest.raises(ValueError, match="duplicate"):
        log.add(_series("a/b"))
