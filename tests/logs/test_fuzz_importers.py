"""Fuzzing every log importer and the `.plan` reader with mutations of real files.

Each case is a seeded mutation of a fixture (byte flips, a cut, a duplicated stretch, a
length field made huge, a run of zeros) and must end in one of two ways: imported, or
refused with the reader's own error and a sentence for the user. Each case must also stay
within the bounds docs/security.md states for the importers: CPU time at most
TIME_FLOOR_S plus TIME_PER_MB_S per MB of input, and Python memory (tracemalloc, numpy
included) at most MEMORY_FLOOR_BYTES plus MEMORY_PER_BYTE times the input.

Every random generator starts from RANDOM_START (and the part's number), so a failure
repeats; the file costs about three minutes of CPU, spread over the parallel workers.
"""

from __future__ import annotations

import bz2
import random
import struct
import time
import tracemalloc
from collections import Counter
from collections.abc import Callable, Iterator
from pathlib import Path

import lz4.frame
import pytest

from logs import LogData, LogFormatError, import_log
from logs.importers.rosbag import ChunkBudget
from logs.synth import synthetic_dataflash, synthetic_ulog
from missions import qgc_plan
from tests.logs.dfi_builder import write_dfi
from tests.logs.test_mission_log import mission_log
from tests.logs.test_rosbag import write_bag
from tests.logs.test_tlog import write_tlog
from tests.support.paths import REAL_ULOGS

RANDOM_START = 306
TIME_FLOOR_S = 2.0
TIME_PER_MB_S = 2.0
MEMORY_FLOOR_BYTES = 64 << 20
MEMORY_PER_BYTE = 64
QGC_PLANS = Path(__file__).resolve().parents[1] / "data" / "qgc"
# A real PX4 log cut down for thousands of cases: all its formats, its first
# ULOG_KEPT_TOPICS subscriptions and their first ULOG_KEPT_DATA data messages.
ULOG_KEPT_TOPICS = 8
ULOG_KEPT_DATA = 300


def _flip(data: bytearray, rng: random.Random) -> bytearray:
    for _ in range(rng.randint(1, 16)):
        data[rng.randrange(len(data))] = rng.randrange(256)
    return data


def _cut(data: bytearray, rng: random.Random) -> bytearray:
    return data[: rng.randrange(1, len(data))]


def _duplicate(data: bytearray, rng: random.Random) -> bytearray:
    start = rng.randrange(len(data))
    span = data[start : start + rng.randint(1, 4096)]
    at = rng.randrange(len(data))
    return data[:at] + span * rng.randint(1, 8) + data[at:]


def _huge_length(data: bytearray, rng: random.Random) -> bytearray:
    field = rng.choice([b"\xff\xff", b"\xff\xff\xff\x7f", b"\xff\xff\xff\xff", b"\x00\x00"])
    at = rng.randrange(len(data))
    data[at : at + len(field)] = field
    return data


def _zeros(data: bytearray, rng: random.Random) -> bytearray:
    at = rng.randrange(len(data))
    return data[:at] + bytes(rng.randint(1, 8192)) + data[at:]


MUTATIONS = [_flip, _cut, _duplicate, _huge_length, _zeros]


def mutants(original: bytes, count: int, seed: int) -> Iterator[bytes]:
    rng = random.Random(seed)
    for _ in range(count):
        data = bytearray(original)
        for _ in range(rng.randint(1, 3)):
            data = rng.choice(MUTATIONS)(data, rng)
            if not data:
                data = bytearray(original[:1])
        yield bytes(data)


def within_bounds(read: Callable[[Path], object], path: Path) -> tuple[object, float, int]:
    """What `read` returned or raised, its CPU seconds and its peak of Python memory."""
    tracemalloc.reset_peak()
    before = tracemalloc.get_traced_memory()[0]
    started = time.process_time()
    try:
        outcome: object = read(path)
    except (LogFormatError, qgc_plan.QgcPlanError) as exc:
        outcome = exc
    spent = time.process_time() - started
    peak = tracemalloc.get_traced_memory()[1] - before
    return outcome, spent, peak


def fuzz(
    read: Callable[[Path], object],
    original: bytes,
    *,
    count: int,
    suffix: str,
    tmp_path,
    part: int = 0,
):  # type: ignore[no-untyped-def]
    """Every mutant imported or cleanly refused, within the time and memory bounds."""
    outcomes: Counter[str] = Counter()
    warm = tmp_path / f"original{suffix}"
    warm.write_bytes(original)
    try:  # the reader's first use loads its modules (pymavlink's dialects, types)
        read(warm)
    except (LogFormatError, qgc_plan.QgcPlanError):
        pass
    tracemalloc.start()
    try:
        for number, data in enumerate(
            mutants(original, count, RANDOM_START + len(suffix) + 1000 * part)
        ):
            path = tmp_path / f"case{suffix}"
            path.write_bytes(data)
            outcome, spent, peak = within_bounds(read, path)
            size = len(data)
            where = f"case {number} ({size} bytes)"
            assert spent <= TIME_FLOOR_S + TIME_PER_MB_S * size / 1e6, f"{where}: {spent:.2f} s"
            assert peak <= MEMORY_FLOOR_BYTES + MEMORY_PER_BYTE * size, f"{where}: {peak} B"
            if isinstance(outcome, Exception):
                message = str(outcome)
                assert message.endswith(".") or isinstance(outcome, qgc_plan.QgcPlanError)
                assert len(message) > 15, f"{where}: {message!r}"
                outcomes["refused"] += 1
            else:
                outcomes["imported"] += 1
    finally:
        tracemalloc.stop()
    assert sum(outcomes.values()) == count
    return outcomes


def _import(path: Path) -> LogData:
    log = import_log(path)
    assert isinstance(log, LogData) and log.series
    return log


def _real_ulog_excerpt(raw: bytes) -> bytes:
    out, pos, topics, data = bytearray(raw[:16]), 16, set(), 0
    while pos + 3 <= len(raw) and data < ULOG_KEPT_DATA:
        end = pos + 3 + (raw[pos] | raw[pos + 1] << 8)
        kind = chr(raw[pos + 2])
        at = pos + 4 if kind == "A" else pos + 3  # a subscription starts with its multi id
        msg_id = raw[at] | raw[at + 1] << 8
        if kind == "A" and len(topics) < ULOG_KEPT_TOPICS:
            topics.add(msg_id)
        if kind == "F" or (kind in "AD" and msg_id in topics):
            out += raw[pos:end]
            data += kind == "D"
        pos = end
    return bytes(out)


def _fixture(kind: str, directory: Path) -> bytes:
    path = directory / f"fixture.{kind}"
    if kind == "ulg":
        return _real_ulog_excerpt((REAL_ULOGS / "sample_log_small.ulg").read_bytes())
    if kind == "synthetic.ulg":
        synthetic_ulog(path, seconds=1)
    elif kind == "bin":
        synthetic_dataflash(path, seconds=1, rate_hz=10)
    elif kind == "tlog":
        write_tlog(path, n=10)
    elif kind in ("bz2.bag", "lz4.bag"):
        write_bag(path, n=5, compression=kind.split(".")[0])
    elif kind == "dfi":
        write_dfi(path)
    else:
        path.write_text(mission_log())
    return path.read_bytes()


# Cases per importer, in parts of FUZZ_PART (each its own seed) so parallel workers share
# them: a .tlog case costs ~10 ms (pymavlink decodes in Python), a bag ~40 ms (rosbags
# builds its type store per file), the others a few ms.
FUZZ_CASES = 2000
FUZZ_PART = 500
FUZZ_KINDS = ["ulg", "bin", "tlog", "bz2.bag", "lz4.bag", "dfi", "json"]


@pytest.mark.parametrize("part", range(FUZZ_CASES // FUZZ_PART))
@pytest.mark.parametrize("kind", FUZZ_KINDS)
def test_every_mutant_of_a_log_imports_or_is_refused_within_bounds(tmp_path, kind, part):
    original = _fixture(kind, tmp_path)
    outcomes = fuzz(
        _import, original, count=FUZZ_PART, suffix=f".{kind}", tmp_path=tmp_path, part=part
    )
    # The fixture itself imports, so the refusals are the mutations' doing, and they break
    # files (a part of 500 mutants of the mission JSON may keep none readable).
    _import(tmp_path / f"original.{kind}")
    assert outcomes["refused"], outcomes


@pytest.mark.parametrize("name", sorted(p.name for p in QGC_PLANS.glob("*.plan")))
def test_every_mutant_of_a_plan_is_read_or_refused_within_bounds(tmp_path, name):
    original = (QGC_PLANS / name).read_bytes()
    outcomes = fuzz(
        lambda p: qgc_plan.import_plan(p.read_bytes()),
        original,
        count=1000,
        suffix=".plan",
        tmp_path=tmp_path,
    )
    assert outcomes["refused"], outcomes


# --- the bombs a fuzzer would take long to find, each refused at once with its reason ---


def _ulog(*messages: tuple[str, bytes]) -> bytes:
    head = b"ULog\x01\x12\x35\x01" + bytes(8)
    return head + b"".join(struct.pack("<HB", len(p), ord(k)) + p for k, p in messages)


def _subscribe(name: bytes) -> tuple[str, bytes]:
    return ("A", b"\x00\x01\x00" + name)


ULOG_BOMBS = {
    "nested arrays multiply": (
        _ulog(
            ("F", b"T0:uint64_t timestamp;uint8_t x"),
            ("F", b"T1:T0[65535] a"),
            ("F", b"T2:T1[65535] b"),
            _subscribe(b"T2"),
        ),
        "larger than a message can carry",
    ),
    "a format contains itself": (
        _ulog(("F", b"T0:uint64_t timestamp;T0 again"), _subscribe(b"T0")),
        "nests deeper than",
    ),
    "formats past the field budget": (
        _ulog(
            ("F", b"T0:uint64_t timestamp;uint8_t[65000] x"),
            ("F", b"T1:uint64_t timestamp;uint8_t[65000] y"),
            _subscribe(b"T0"),
            ("A", b"\x00\x02\x00T1"),
        ),
        "more fields",
    ),
}


@pytest.mark.parametrize("name", sorted(ULOG_BOMBS))
def test_ulog_format_bombs_are_refused_at_once_with_a_reason(tmp_path, name):
    data, reason = ULOG_BOMBS[name]
    path = tmp_path / "bomb.ulg"
    path.write_bytes(data)
    outcome, spent, peak = _bounded(path)
    assert isinstance(outcome, LogFormatError) and reason in str(outcome), outcome
    assert spent < 1.0 and peak < 16 << 20


def test_a_ulog_of_garbage_costs_one_read_not_one_per_byte(tmp_path):
    path = tmp_path / "zeros.ulg"
    path.write_bytes(_ulog() + bytes(2 << 20))
    outcome, spent, _ = _bounded(path)
    assert isinstance(outcome, LogFormatError)
    # Within the importers' stated bound for its size (docs/security.md); when the reader
    # was quadratic in the bytes it skipped, 20 KB took 9 s.
    size_mb = path.stat().st_size / 1e6
    assert spent <= TIME_FLOOR_S + TIME_PER_MB_S * size_mb, spent


_COMPRESSORS = {"bz2": bz2.compress, "lz4": lz4.frame.compress}


@pytest.mark.parametrize("compression", ["bz2", "lz4"])
def test_a_bag_chunk_that_decompresses_past_its_ratio_is_refused(tmp_path, compression):
    path = write_bag(tmp_path / "flight.bag", n=20, compression=compression)
    budget = ChunkBudget("flight.bag", ratio=2.0, total=1 << 30)
    with pytest.raises(LogFormatError, match="compression bomb"):
        budget.decompress(compression, _COMPRESSORS[compression](bytes(10**6)))
    assert isinstance(import_log(path), LogData)  # a real compressed bag stays readable


def test_a_zip_whose_members_share_their_bytes_is_refused(tmp_path):
    path = write_dfi(tmp_path / "flight.dfi")
    raw = bytearray(path.read_bytes())
    central = raw.rfind(b"PK\x01\x02")
    # Claim a compressed size past the archive for the last member of the directory.
    raw[central + 20 : central + 24] = struct.pack("<I", len(raw) * 4)
    path.write_bytes(bytes(raw))
    outcome, _, _ = _bounded(path)
    assert isinstance(outcome, LogFormatError) and "ZIP bomb" in str(outcome), outcome


def test_a_plan_nested_past_json_depth_is_refused(tmp_path):
    outcome, spent, _ = within_bounds(
        lambda p: qgc_plan.import_plan(p.read_bytes()), _write(tmp_path, b"[" * 200_000)
    )
    assert isinstance(outcome, qgc_plan.QgcPlanError), outcome
    assert spent < 1.0


def _write(tmp_path: Path, data: bytes) -> Path:
    path = tmp_path / "deep.plan"
    path.write_bytes(data)
    return path


def _bounded(path: Path) -> tuple[object, float, int]:
    tracemalloc.start()
    try:
        return within_bounds(import_log, path)
    finally:
        tracemalloc.stop()
