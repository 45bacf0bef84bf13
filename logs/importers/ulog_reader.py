"""A vectorised reader of PX4 ULog files that returns what pyulog's `ULog` returns.

The file format is PX4's "ULog File Format": a 16-byte header, then messages of
`uint16 size, uint8 type, payload`. pyulog decodes every message in Python and appends each
data payload to a buffer; here one tight loop only follows the message sizes, and every data
message of a subscription is then gathered at once through a numpy view whose records start
at any byte (stride 1), so the per-message Python work is a few operations.

Two passes over the file, each in chunks of CHUNK_BYTES: the first follows the headers,
handles the non-data messages and keeps, per chunk, where each subscription's records start
(4 bytes a message); the second, once every topic's row count is known, copies the records
of each chunk, a block at a time, to where a RecordSink wants them. `read_ulog` keeps them:
its sink allocates each topic's array once at its full size and the records are copied
straight into it, so memory holds the decoded data once plus one chunk (no topic is ever
held in parts and then joined). `stream_ulog` hands them on: its sink gets every topic's
row count before the first record and each block of records in file order, and may write
them out and drop them, so memory holds one chunk and one block.
Corruption is handled like pyulog: an impossible header moves on by one byte (or to the
next sync sequence when the log has them), a data message of an unknown subscription or an
impossible size is skipped, and the log is flagged corrupt.

Bounds (a hostile file costs a fixed multiple of its size, never more):
- Formats are measured before anything is built from them: a subscribed format larger than
  a message can carry (a uint16 size, ULog File Format), nested deeper than MAX_NESTING,
  containing itself, or whose fields would pass the file's field budget (FIELD_FLOOR plus
  one per BYTES_PER_FIELD of file) refuses the file, so nested arrays that multiply
  (`T1: T0[65535] a`, `T2: T1[65535] b`) are never expanded. A format name defined twice
  keeps its first definition (PX4 defines each once), so a measure never goes stale.
- After an impossible header the reader checks each header as it goes (CAREFUL_BYTES of
  file at a time) until CLEAN_BYTES in a row are sound, then walks again in chunks that
  start at RESUME_BYTES and double: a file of garbage is read once, not once per byte.
"""

from __future__ import annotations

import struct
from array import array
from collections.abc import Callable
from dataclasses import dataclass, field
from io import BufferedReader
from pathlib import Path
from typing import Protocol

import numpy as np

MAGIC = b"ULog\x01\x12\x35"
SYNC = b"\x2f\x73\x13\x20\x25\x0c\xbb\x12"
HEADER_BYTES = 16
CHUNK_BYTES = 64 << 20
# Records copied from a chunk to the sink at a time: at most this many, and at most
# COPY_BYTES of them (a block is a sink's working buffer).
COPY_BLOCK = 1 << 16
COPY_BYTES = 4 << 20
# Record starts are kept in blocks of this many: allocations this large are mapped pages of
# their own (glibc maps anything over 32 MiB), so a block the second pass has used up goes
# back to the system instead of leaving holes in the heap.
STARTS_BLOCK = 16 << 20
# The same corruption heuristic as pyulog: a header this implausible is not a message.
MAX_PLAUSIBLE_SIZE = 10_000
KNOWN_TYPES = np.frombuffer(b"FDIMPQARSOLCB", dtype=np.uint8)
KNOWN_TYPE_SET = frozenset(KNOWN_TYPES.tolist())
IS_KNOWN_TYPE = np.isin(np.arange(256), KNOWN_TYPES)
# A message header (ULog File Format): its payload's size, then its type.
HEADER = np.dtype([("size", "<u2"), ("type", "u1")])
# A message's size is a uint16, so a data record is at most this long.
MAX_MESSAGE_BYTES = 0xFFFF
MAX_NESTING = 16
FIELD_FLOOR = 1 << 13
BYTES_PER_FIELD = 16
CAREFUL_BYTES = 1 << 20
CLEAN_BYTES = 1 << 17
RESUME_BYTES = 1 << 20
DATA = ord("D")
DATA_SECTION_STARTS = (ord("A"), ord("L"), ord("C"))

# ULog field type -> (numpy type, struct code); bool and char decode as int8 like pyulog.
TYPES: dict[str, tuple[str, str]] = {
    "int8_t": ("i1", "b"),
    "uint8_t": ("u1", "B"),
    "int16_t": ("<i2", "h"),
    "uint16_t": ("<u2", "H"),
    "int32_t": ("<i4", "i"),
    "uint32_t": ("<u4", "I"),
    "int64_t": ("<i8", "q"),
    "uint64_t": ("<u8", "Q"),
    "float": ("<f4", "f"),
    "double": ("<f8", "d"),
    "bool": ("i1", "?"),
    "char": ("i1", "c"),
}


class UlogError(ValueError):
    """The file is not a ULog this reader can parse."""


class UlogBoundError(UlogError):
    """The file declares more than its size can justify: refused whole, not skipped."""


@dataclass
class Dataset:
    """One topic instance: its fields as numpy arrays, `timestamp` among them."""

    name: str
    multi_id: int
    msg_id: int
    data: dict[str, np.ndarray]


@dataclass(frozen=True, eq=False)
class Topic:
    """One topic instance as the first pass found it: its record type and row count (a
    topic subscribed again is one Topic). Each is made once: it compares by identity."""

    name: str
    multi_id: int
    msg_id: int
    dtype: np.dtype
    count: int


class RecordSink(Protocol):
    """Where the second pass puts the records: `begin` gets every topic (with the rest of
    the log, all but its data, in `log`) before the first record; then, in file order and a
    block at a time, `rows` says where the next `count` records of a topic go (an array of
    the topic's dtype, rows `at` to `at + count` of its data) and `filled` is told once they
    are there."""

    def begin(self, log: UlogFile, topics: list[Topic]) -> None: ...

    def rows(self, topic: Topic, at: int, count: int) -> np.ndarray: ...

    def filled(self, topic: Topic, rows: np.ndarray) -> None: ...


@dataclass
class LoggedMessage:
    timestamp: int
    log_level: int
    message: str


@dataclass
class Subscription:
    name: str
    multi_id: int
    msg_id: int
    dtype: np.dtype
    max_size: int
    count: int = 0

    @property
    def key(self) -> tuple[str, int, int]:
        """Subscriptions with the same key (a topic subscribed again) make one Dataset."""
        return self.name, self.multi_id, self.msg_id


@dataclass
class _Piece:
    """A window of the file read by the first pass, and the start of each data record in
    it (relative to `pos`) by subscription, in file order."""

    pos: int
    length: int
    picks: list[tuple[Subscription, np.ndarray]] = field(default_factory=list)


@dataclass
class UlogFile:
    start_timestamp: int = 0
    msg_info_dict: dict[str, object] = field(default_factory=dict)
    initial_parameters: dict[str, object] = field(default_factory=dict)
    changed_parameters: list[tuple[str, object]] = field(default_factory=list)
    logged_messages: list[LoggedMessage] = field(default_factory=list)
    data_list: list[Dataset] = field(default_factory=list)
    file_corruption: bool = False
    dropouts_ms: int = 0


def read_ulog(path: Path, progress: Callable[[float], None] | None = None) -> UlogFile:
    """Parse the whole file at `path`, every topic's data in memory (`data_list`); raises
    UlogError when it is not a ULog."""
    sink = _Arrays()
    log = stream_ulog(path, sink, progress)
    log.data_list = sink.datasets()
    return log


def stream_ulog(
    path: Path, sink: RecordSink, progress: Callable[[float], None] | None = None
) -> UlogFile:
    """Parse the file at `path`, handing each topic's records to `sink` as they are read;
    the result holds everything else (its `data_list` stays empty). Raises UlogError when
    the file is not a ULog, before the sink gets anything. `progress` gets the fraction
    of the work done, now and then."""
    with open(path, "rb") as handle:
        return _Reader(handle, sink, progress or _quiet).read()


def _quiet(_fraction: float) -> None:
    """No progress wanted."""


def _text(raw: bytes) -> str:
    return raw.split(b"\0", 1)[0].decode("utf-8", "ignore")


class _Reader:
    def __init__(
        self, handle: BufferedReader, sink: RecordSink, progress: Callable[[float], None]
    ) -> None:
        self.file = handle
        self.sink = sink
        self.progress = progress
        self.size = handle.seek(0, 2)
        self.out = UlogFile()
        self.formats: dict[str, list[tuple[str, int, str]]] = {}
        self.subscriptions: dict[int, Subscription] = {}
        self.finished: list[Subscription] = []
        self.pieces: list[_Piece] = []
        self.starts = _Blocks()
        self.buffer = bytearray()
        self.in_data = False
        self.has_sync = True
        self.careful = False
        self.measures: dict[str, tuple[int, int]] = {}
        self.layouts: dict[str, tuple[np.dtype, int]] = {}
        self.fields_left = FIELD_FLOOR + self.size // BYTES_PER_FIELD

    def read(self) -> UlogFile:
        head = self._bytes(0, HEADER_BYTES)
        if len(head) < HEADER_BYTES:
            raise UlogError("the header is too short")
        if head[:7] != MAGIC:
            raise UlogError("the header does not start with the ULog magic bytes")
        self.out.start_timestamp = struct.unpack_from("<Q", head, 8)[0]
        start = HEADER_BYTES
        for end in self._segment_ends():
            self._read_segment(start, end)
            start = end
        self._finish()
        return self.out

    def _segment_ends(self) -> list[int]:
        """Appended data (a flag bit and offsets in the first message) is read as separate
        segments: the main data up to the first offset, then each appended part."""
        size = self.size
        flags = self._bytes(HEADER_BYTES, 3 + 40)
        if len(flags) < 3 + 40 or flags[2] != ord("B"):
            return [size]
        incompat = flags[3 + 8 : 3 + 16]
        if incompat[0] & ~1 or any(incompat[1:]):
            raise UlogError("the log sets incompatible flags this reader does not know")
        offsets = [o for o in struct.unpack_from("<3Q", flags, 3 + 16) if o]
        if not incompat[0] & 1 or not offsets:
            return [size]
        if any(o > size for o in offsets):
            self.out.file_corruption = True
            offsets = [o for o in offsets if o <= size]
        return [*offsets, size]

    def _read_segment(self, pos: int, end: int) -> None:
        span = CHUNK_BYTES
        while pos < end:
            if self.careful:
                pos, span = self._careful(pos, end), RESUME_BYTES
                continue
            chunk_end = min(end, pos + span)
            self.progress(0.5 * pos / self.size)
            chunk = self._chunk(pos, chunk_end - pos)
            offsets, stop = _walk(chunk)
            headers = _headers(chunk, offsets)
            good, bad = self._check(headers)
            self._process(chunk, headers[:good], pos)
            if bad is not None:
                pos, self.careful = pos + bad, True
            elif chunk_end == end:
                return  # what is left is a message cut off by the end of the file
            elif stop == 0:
                span *= 2  # one message longer than a chunk
            else:
                pos, span = pos + stop, min(span * 2, CHUNK_BYTES)

    def _check(self, headers: _Headers) -> tuple[int, int | None]:
        """How many messages come before the first impossible header, and where it was."""
        types, sizes = headers.types, headers.sizes
        bad = ~IS_KNOWN_TYPE[types] & ((types == 0) | (sizes == 0) | (sizes > MAX_PLAUSIBLE_SIZE))
        if not bad.any():
            return len(types), None
        first = int(np.argmax(bad))
        self.out.file_corruption = True
        return first, int(headers.offsets[first])

    def _careful(self, pos: int, end: int) -> int:
        """From an impossible header at `pos`: check every header of the next CAREFUL_BYTES,
        skipping past bad ones, and leave careful mode after CLEAN_BYTES of sound ones.
        Returns where reading goes on."""
        window = self._bytes(pos, min(end - pos, CAREFUL_BYTES))
        scan = _scan(window, self.has_sync)
        self.out.file_corruption |= scan.corrupt
        self._process(window, _headers(window, np.frombuffer(scan.offsets, dtype=np.int64)), pos)
        self.careful = not scan.clean
        if scan.needs_sync:  # the next sync sequence lies past this window
            return self._recover(pos + scan.stop, end)
        if pos + len(window) == end and not scan.clean:
            return end  # what is left is a message cut off by the end of the file
        return pos + scan.stop

    def _recover(self, pos: int, end: int) -> int:
        """The position after the next sync sequence from `pos`; when the rest of the file
        has none, `pos` itself, and headers are tried byte by byte from then on."""
        at, span = pos, CAREFUL_BYTES
        while at < end:
            window = self._bytes(at, min(span, end - at))
            found = window.find(SYNC)
            if found >= 0:
                return at + found + len(SYNC)
            if at + len(window) >= end:
                break
            at, span = at + len(window) - len(SYNC) + 1, min(span * 2, CHUNK_BYTES)
        self.has_sync = False
        return pos

    def _bytes(self, pos: int, count: int) -> bytes:
        self.file.seek(pos)
        return self.file.read(count)

    def _chunk(self, pos: int, count: int) -> memoryview:
        """`count` bytes of the file from `pos`, read into one buffer kept for every chunk
        (a fresh one each time costs its pages again)."""
        if len(self.buffer) < count:
            self.buffer = bytearray(count)
        self.file.seek(pos)
        view = memoryview(self.buffer)
        return view[: self.file.readinto(view[:count])]

    def _process(self, chunk: bytes | memoryview, headers: _Headers, pos: int) -> None:
        """Handle the few non-data messages in order; sort the data messages between two
        subscriptions to their subscription in bulk. `chunk` is the file from `pos`."""
        piece = _Piece(pos, len(chunk))
        others = np.flatnonzero(headers.types != DATA)
        first = 0
        for index in others.tolist():
            at = int(headers.offsets[index])
            kind = chunk[at + 2]
            if kind == ord("A") or kind == ord("R"):
                self._pick(piece, chunk, headers[first:index])
                first = index + 1
            size = chunk[at] | chunk[at + 1] << 8
            self._message(kind, bytes(chunk[at + 3 : at + 3 + size]))
        self._pick(piece, chunk, headers[first:])
        if piece.picks:
            self.pieces.append(piece)

    def _pick(self, piece: _Piece, chunk: bytes | memoryview, headers: _Headers) -> None:
        """Note where the records of each current subscription start; a data message of no
        subscription, or shorter or longer than its format allows, is left out."""
        data = headers.types == DATA
        offsets, sizes = headers.offsets[data], headers.sizes[data] - 2
        if (sizes < 0).any():  # too short to name its subscription: skipped, like garbage
            self.out.file_corruption = True
            offsets, sizes = offsets[sizes >= 0], sizes[sizes >= 0]
        if not len(offsets):
            return
        ids = _records(chunk, np.dtype("<u2"))[offsets + 3]
        # Grouped by subscription in one stable sort: each group stays in file order.
        order = np.argsort(ids, kind="stable")
        for group in np.split(order, np.flatnonzero(np.diff(ids[order])) + 1):
            sub = self.subscriptions.get(int(ids[group[0]]))
            if sub is None:
                self.out.file_corruption = True
                continue
            size = sizes[group]
            fits = (size >= sub.dtype.itemsize) & (size <= sub.max_size)
            if not fits.all():
                self.out.file_corruption = True
                group = group[fits]
            if len(group):
                starts = offsets[group] + 5
                piece.picks.append((sub, self.starts.keep(starts, piece.length)))
                sub.count += len(starts)

    def _message(self, kind: int, payload: bytes) -> None:
        handler = _HANDLERS.get(kind)
        if kind in DATA_SECTION_STARTS:
            self.in_data = True
        if handler is not None:
            try:
                handler(self, payload)
            except UlogBoundError:
                raise
            except (IndexError, KeyError, ValueError, struct.error):
                self.out.file_corruption = True

    def _format(self, payload: bytes) -> None:
        name, _, fields = _text(payload).partition(":")
        if name in self.formats:
            self.out.file_corruption = True  # PX4 defines each format once; the first stands
            return
        self.formats[name] = [_field(f) for f in fields.split(";") if f]

    def _info(self, payload: bytes) -> None:
        key, value = _key_value(payload)
        if key is not None:
            self.out.msg_info_dict[key] = value

    def _parameter(self, payload: bytes) -> None:
        key, value = _key_value(payload)
        if key is None:
            return
        if self.in_data:
            self.out.changed_parameters.append((key, value))
        else:
            self.out.initial_parameters[key] = value

    def _subscribe(self, payload: bytes) -> None:
        multi_id, msg_id = payload[0], struct.unpack_from("<H", payload, 1)[0]
        name = _text(payload[3:])
        dtype, max_size = self._layout(name)
        self._retire(msg_id)
        self.subscriptions[msg_id] = Subscription(name, multi_id, msg_id, dtype, max_size)

    def _layout(self, name: str) -> tuple[np.dtype, int]:
        """The record type of a format and its full size, built once per format and only
        after its measure fits a message and the file's field budget."""
        known = self.layouts.get(name)
        if known is not None:
            return known
        size, count = self._measure(name, 0)
        if count > self.fields_left:
            raise UlogBoundError(
                f"the formats declare more fields ({count} in {name!r}) than a file of "
                f"{self.size} bytes can carry"
            )
        self.fields_left -= count
        fields = _flatten(self.formats, name, "")
        while fields and fields[-1][0].startswith("_padding"):
            fields.pop()  # PX4 leaves trailing padding out of the data messages
        layout = self.layouts[name] = (np.dtype([(n, TYPES[t][0]) for n, t in fields]), size)
        return layout

    def _measure(self, name: str, depth: int) -> tuple[int, int]:
        """(bytes, fields) of a format once flattened, computed without flattening it."""
        known = self.measures.get(name)
        if known is not None:
            return known
        if depth > MAX_NESTING:
            raise UlogBoundError(f"the format {name!r} nests deeper than {MAX_NESTING} levels")
        size = count = 0
        for kind, length, _ in self.formats[name]:
            if kind in TYPES:
                one = (np.dtype(TYPES[kind][0]).itemsize, 1)
            else:
                one = self._measure(kind, depth + 1)
            size += one[0] * max(length, 1)
            count += one[1] * max(length, 1)
            if size > MAX_MESSAGE_BYTES:
                raise UlogBoundError(f"the format {name!r} is larger than a message can carry")
        self.measures[name] = (size, count)
        return size, count

    def _unsubscribe(self, payload: bytes) -> None:
        self._retire(struct.unpack_from("<H", payload)[0])

    def _retire(self, msg_id: int) -> None:
        old = self.subscriptions.pop(msg_id, None)
        if old is not None:
            self.finished.append(old)

    def _logging(self, payload: bytes) -> None:
        level, timestamp = struct.unpack_from("<BQ", payload)
        self.out.logged_messages.append(LoggedMessage(timestamp, level, _text(payload[9:])))

    def _logging_tagged(self, payload: bytes) -> None:
        # A tagged string (ULog File Format, message 'C'): level, the tag of the process
        # that logged it, then as 'L'. One list, in the order the file logged them.
        level, _tag, timestamp = struct.unpack_from("<BHQ", payload)
        self.out.logged_messages.append(LoggedMessage(timestamp, level, _text(payload[11:])))

    def _dropout(self, payload: bytes) -> None:
        self.out.dropouts_ms += struct.unpack_from("<H", payload)[0]

    def _finish(self) -> None:
        """The second pass: the sink learns every topic, then gets its records chunk by
        chunk in file order."""
        topics = self._topics()
        self.buffer = bytearray()
        self.sink.begin(self.out, list(topics.values()))
        filled = dict.fromkeys(topics, 0)
        pieces, self.pieces, self.starts = self.pieces, [], _Blocks()
        total = max(sum(p.length for p in pieces), 1)
        done = 0
        pieces.reverse()
        # One buffer for every chunk: the second pass adds one chunk and one block to what
        # the sink keeps.
        buffer = memoryview(bytearray(max((p.length for p in pieces), default=0)))
        while pieces:
            piece = pieces.pop()
            self.progress(0.5 + 0.5 * done / total)
            done += piece.length
            self.file.seek(piece.pos)
            chunk = buffer[: self.file.readinto(buffer[: piece.length])]
            for sub, starts in piece.picks:
                topic = topics[sub.key]
                filled[sub.key] = _copy(chunk, starts, self.sink, topic, filled[sub.key])
            del chunk, piece, starts
        del buffer
        self.progress(1.0)

    def _topics(self) -> dict[tuple[str, int, int], Topic]:
        """Every subscription with data, those of one key as one topic, in the order of
        the datasets (by name and instance, first subscribed first)."""
        counts: dict[tuple[str, int, int], int] = {}
        dtypes: dict[tuple[str, int, int], np.dtype] = {}
        for sub in [*self.finished, *self.subscriptions.values()]:
            if sub.count:
                counts[sub.key] = counts.get(sub.key, 0) + sub.count
                dtypes.setdefault(sub.key, sub.dtype)
        keys = sorted(counts, key=lambda key: key[:2])  # stable: ties keep their order
        return {key: Topic(*key, dtype=dtypes[key], count=counts[key]) for key in keys}


class _Arrays:
    """The sink of read_ulog: each topic's records in one array of its full size (np.empty
    only reserves: a page counts as memory once a record is copied onto it)."""

    def __init__(self) -> None:
        self.arrays: dict[Topic, np.ndarray] = {}

    def begin(self, log: UlogFile, topics: list[Topic]) -> None:
        self.arrays = {topic: np.empty(topic.count, dtype=topic.dtype) for topic in topics}

    def rows(self, topic: Topic, at: int, count: int) -> np.ndarray:
        return self.arrays[topic][at : at + count]

    def filled(self, topic: Topic, rows: np.ndarray) -> None:
        """The records are already in place."""

    def datasets(self) -> list[Dataset]:
        return [
            Dataset(
                t.name, t.multi_id, t.msg_id, {n: records[n] for n in records.dtype.names or ()}
            )
            for t, records in self.arrays.items()
        ]


_HANDLERS = {
    ord("F"): _Reader._format,
    ord("I"): _Reader._info,
    ord("P"): _Reader._parameter,
    ord("A"): _Reader._subscribe,
    ord("R"): _Reader._unsubscribe,
    ord("L"): _Reader._logging,
    ord("C"): _Reader._logging_tagged,
    ord("O"): _Reader._dropout,
}


class _Blocks:
    """Record starts within a chunk, copied into STARTS_BLOCK-long uint32 blocks; each kept
    array is a view that holds its block, freed once no view of it is left."""

    def __init__(self) -> None:
        self.block = np.empty(0, dtype=np.uint32)
        self.used = 0

    def keep(self, starts: np.ndarray, length: int) -> np.ndarray:
        # Offsets within a chunk fit 4 bytes unless the chunk grew past 4 GiB for one message.
        if length > 0xFFFFFFFF or len(starts) > STARTS_BLOCK:
            return starts.copy()
        if self.used + len(starts) > len(self.block):
            self.block, self.used = np.empty(STARTS_BLOCK, dtype=np.uint32), 0
        kept = self.block[self.used : self.used + len(starts)]
        kept[:] = starts
        self.used += len(starts)
        return kept


def _walk(buf: bytes | memoryview) -> tuple[np.ndarray, int]:
    """Start offsets of the whole messages of `buf`, and where the walk stopped (the end,
    or a message cut off by it). This loop is the only per-message Python work of the
    reader, so it checks nothing: it follows the sizes until one leads past the end of
    `buf` (an IndexError), and the last few offsets, which may not be whole, are checked
    after."""
    offsets = array("q")
    add = offsets.append
    pos = 0
    try:
        while True:
            add(pos)
            pos += 3 + (buf[pos] | buf[pos + 1] << 8)
    except IndexError:
        pass
    end = len(buf)
    whole = len(offsets)
    while whole:
        at = offsets[whole - 1]
        if at + 3 <= end and at + 3 + (buf[at] | buf[at + 1] << 8) <= end:
            break
        whole -= 1
    return np.frombuffer(offsets, dtype=np.int64)[:whole], offsets[whole]


@dataclass
class _Headers:
    """The headers of some messages of a chunk: where each starts, its type and size."""

    offsets: np.ndarray
    types: np.ndarray
    sizes: np.ndarray

    def __getitem__(self, rows: slice) -> _Headers:
        return _Headers(self.offsets[rows], self.types[rows], self.sizes[rows])


def _headers(chunk: bytes | memoryview, offsets: np.ndarray) -> _Headers:
    """The headers of the messages of `chunk` at `offsets`, gathered in one go."""
    found = _records(chunk, HEADER)[offsets]
    return _Headers(offsets, found["type"], found["size"].astype(np.int64))


@dataclass
class _Scan:
    offsets: array
    stop: int = 0
    corrupt: bool = False
    clean: bool = False
    needs_sync: bool = False


def _scan(buf: bytes, has_sync: bool) -> _Scan:
    """The careful walk after corruption: each header is checked before it is followed, a
    bad one skipped to the next sync sequence (or the next byte when the log has none);
    stops after CLEAN_BYTES of sound messages in a row, or at the end of `buf`."""
    scan = _Scan(array("q"))
    pos = sound_from = 0
    limit = len(buf) - 3
    candidates: np.ndarray | None = None
    while pos <= limit:
        size = buf[pos] | buf[pos + 1] << 8
        if pos + 3 + size > len(buf):
            break  # like pyulog, a header whose message runs past the end ends the file
        kind = buf[pos + 2]
        if kind not in KNOWN_TYPE_SET and (kind == 0 or size == 0 or size > MAX_PLAUSIBLE_SIZE):
            scan.corrupt = True
            found = buf.find(SYNC, pos + 1) if has_sync else -1
            if has_sync and found < 0:
                scan.stop, scan.needs_sync = pos + 1, True
                return scan
            if found < 0 and candidates is None:
                candidates = _plausible(buf)
            if found >= 0:
                pos = sound_from = found + len(SYNC)
            else:  # the next byte whose header could be one (a run of zeros is skipped whole)
                at = int(candidates.searchsorted(pos + 1))  # type: ignore[union-attr]
                pos = sound_from = int(candidates[at]) if at < len(candidates) else limit + 1
            continue
        scan.offsets.append(pos)
        pos += 3 + size
        if pos - sound_from >= CLEAN_BYTES:
            scan.clean = True
            break
    scan.stop = pos
    return scan


def _plausible(buf: bytes) -> np.ndarray:
    """Every offset of `buf` where _scan would not just step on: a header that passes the
    corruption check, or one whose message runs past the end of `buf`."""
    raw = np.frombuffer(buf, dtype=np.uint8)
    if len(raw) < 3:
        return np.zeros(0, dtype=np.int64)
    kinds = raw[2:]
    sizes = raw[:-2] | (raw[1:-1].astype(np.int64) << 8)
    good = np.isin(kinds, KNOWN_TYPES) | (
        (kinds != 0) & (sizes != 0) & (sizes <= MAX_PLAUSIBLE_SIZE)
    )
    past_end = np.arange(3, len(raw) + 1) + sizes > len(raw)
    return np.flatnonzero(good | past_end)


def _records(chunk: bytes | memoryview, dtype: np.dtype) -> np.ndarray:
    """Every byte of `chunk` as the start of a record of `dtype` (overlapping, read-only):
    indexing it with message offsets copies exactly those records."""
    count = len(chunk) - dtype.itemsize + 1
    return np.ndarray((max(count, 0),), dtype=dtype, buffer=chunk, strides=(1,))


def _copy(chunk: memoryview, starts: np.ndarray, sink: RecordSink, topic: Topic, at: int) -> int:
    """The records of `chunk` at `starts` handed to `sink` as rows `at` onwards of `topic`,
    a block at a time; returns the row after the last one. Copied as opaque records of the
    same size: the same bytes, several times faster than field by field."""
    opaque = np.dtype(f"V{topic.dtype.itemsize}")
    records = _records(chunk, opaque)
    step = max(1, min(COPY_BLOCK, COPY_BYTES // opaque.itemsize))
    for block in range(0, len(starts), step):
        picked = starts[block : block + step]
        rows = sink.rows(topic, at, len(picked))
        rows.view(opaque)[:] = records[picked]
        sink.filled(topic, rows)
        at += len(picked)
    return at


def _field(text: str) -> tuple[str, int, str]:
    kind, name = text.split(" ", 1)
    if "[" not in kind:
        return kind, 0, name
    base, _, rest = kind.partition("[")
    length = int(rest.rstrip("]"))
    if not 0 <= length <= 0xFFFF:
        raise ValueError(f"invalid array size {length}")
    return base, length, name


def _flatten(formats: dict, name: str, prefix: str) -> list[tuple[str, str]]:
    """Nested types flattened to `outer.inner` and arrays to `name[i]`, as pyulog names them."""
    out: list[tuple[str, str]] = []
    for kind, length, field_name in formats[name]:
        names = (
            [f"{prefix}{field_name}[{i}]" for i in range(length)]
            if length
            else [f"{prefix}{field_name}"]
        )
        for full in names:
            if kind in TYPES:
                out.append((full, kind))
            else:
                out.extend(_flatten(formats, kind, full + "."))
    return out


def _key_value(payload: bytes) -> tuple[str | None, object]:
    """An info or parameter message: `uint8 key_len, "type name", value`."""
    key_len = payload[0]
    kind, _, key = _text(payload[1 : 1 + key_len]).partition(" ")
    raw = payload[1 + key_len :]
    if not key:
        return None, None
    if kind.startswith("char["):
        return key, _text(raw)
    if kind in TYPES:
        return key, struct.unpack("<" + TYPES[kind][1], raw)[0]
    return key, bytes(raw)
