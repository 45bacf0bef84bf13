"""Whatever the bytes, import_log returns a log or raises LogFormatError: the worker survives."""

import json
from collections.abc import Iterator

import numpy as np
import pytest

from logs import LogData, LogFormatError, import_log
from logs.synth import synthetic_dataflash, synthetic_ulog
from tests.logs.dfi_builder import write_dfi
from tests.logs.test_mission_log import mission_log
from tests.logs.test_rosbag import write_bag
from tests.logs.test_tlog import write_tlog


def _make(kind, path):
    if kind == "ulg":
        synthetic_ulog(path, seconds=1)
    elif kind == "bin":
        synthetic_dataflash(path, seconds=1, rate_hz=50)
    elif kind == "tlog":
        write_tlog(path, n=10)
    elif kind == "bag":
        write_bag(path, n=10)
    elif kind == "dfi":
        write_dfi(path)
    else:
        path.write_text(mission_log())
    return path


def damaged_copies(original: bytes, rng: np.random.Generator, count: int = 24) -> Iterator[bytes]:
    """Copies of a file, every other one cut short at a random byte, the rest with 1 to 19
    bytes overwritten at random."""
    for trial in range(count):
        data = bytearray(original)
        if trial % 2:
            data = data[: int(rng.integers(1, len(data)))]
        else:
            for at in rng.integers(0, len(data), size=int(rng.integers(1, 20))):
                data[at] = int(rng.integers(0, 256))
        yield bytes(data)


@pytest.mark.parametrize("kind", ["ulg", "bin", "tlog", "bag", "dfi", "json"])
def test_truncated_or_corrupted_files_never_raise_anything_else(tmp_path, kind):
    original = _make(kind, tmp_path / f"good.{kind}").read_bytes()
    rng = np.random.default_rng(len(kind))
    outcomes = {"read": 0, "rejected": 0}
    for trial, data in enumerate(damaged_copies(original, rng)):
        path = tmp_path / f"bad{trial}.{kind}"
        path.write_bytes(data)
        try:
            log = import_log(path)
        except LogFormatError as exc:
            assert str(exc).endswith(".") and len(str(exc)) > 20
            outcomes["rejected"] += 1
        else:
            assert isinstance(log, LogData) and log.series
            json.dumps(log.warnings)
            outcomes["read"] += 1
    assert outcomes["rejected"] + outcomes["read"] == 24
