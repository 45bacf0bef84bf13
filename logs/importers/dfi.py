"""DFI recordings (docs/dfi-format.md): a ZIP archive with
description.xml and comma- or tab-separated value files, one per timeline layer."""

from __future__ import annotations

import io
import itertools
import posixpath
import xml.parsers.expat
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from logs.importers.base import Limits, LogFormatError, Progress, describe
from logs.series import LogData, Series, join

TIME_UNITS_NS = {
    "nanoseconds": 1,
    "microseconds": 1_000,
    "milliseconds": 1_000_000,
    "seconds": 1_000_000_000,
}
SEPARATORS = {"comma": ",", "tab": "\t"}
CHUNK_LINES = 100_000
COLUMN_TAGS = ("intQuantity", "doubleQuantity", "intEnumeration", "time")
# A tiny archive may compress far better than any honest large one; judge ratio above this.
RATIO_FLOOR_BYTES = 1 << 20


@dataclass
class Element:
    tag: str
    attrs: dict[str, str]
    children: list[Element] = field(default_factory=list)


@dataclass
class Column:
    tag: str
    path: list[str]  # group names then the column's own name
    attrs: dict[str, str]
    labels: dict[int, str] | None = None
    direct_time: bool = False


def parse_xml(data: bytes) -> Element:
    """Parse description.xml with expat, refusing any DTD so entity expansion cannot happen."""
    parser = xml.parsers.expat.ParserCreate()
    stack: list[Element] = []
    root: list[Element] = []

    def refuse_dtd(*_args: object) -> None:
        raise LogFormatError(
            "description.xml declares a DTD or entities, which are refused for safety."
        )

    def start(tag: str, attrs: dict[str, str]) -> None:
        el = Element(tag, attrs)
        if stack:
            stack[-1].children.append(el)
        else:
            root.append(el)
        stack.append(el)

    def end(_tag: str) -> None:
        stack.pop()

    parser.StartDoctypeDeclHandler = refuse_dtd
    parser.EntityDeclHandler = refuse_dtd
    parser.StartElementHandler = start
    parser.EndElementHandler = end
    try:
        parser.Parse(data, True)
    except xml.parsers.expat.ExpatError as exc:
        raise LogFormatError(f"description.xml is not well-formed XML: {describe(exc)}.") from exc
    return root[0]


def _required(el: Element, attr: str, where: str) -> str:
    value = el.attrs.get(attr)
    if value is None or value == "":
        raise LogFormatError(f"description.xml: <{el.tag}> {where}has no '{attr}' attribute.")
    return value


def _columns(top: Element) -> list[Column]:
    columns: list[Column] = []

    def visit(el: Element, groups: list[str], direct: bool) -> None:
        for child in el.children:
            if child.tag == "group":
                visit(child, groups + [_required(child, "name", "")], False)
            elif child.tag in COLUMN_TAGS:
                columns.append(_column(child, groups, direct))
            else:
                raise LogFormatError(f"description.xml: unknown element <{child.tag}> in a group.")

    visit(top, [], True)
    return columns


def _column(el: Element, groups: list[str], direct: bool) -> Column:
    if el.tag == "time":
        unit = el.attrs.get("unit")
        if unit not in TIME_UNITS_NS:
            raise LogFormatError(
                f"description.xml: unknown time unit {unit!r} (expected one of {', '.join(TIME_UNITS_NS)})."
            )
        source = el.attrs.get("source")
        if source not in ("recorder", "board"):
            raise LogFormatError(
                f"description.xml: unknown time source {source!r} (expected recorder or board)."
            )
        name = el.attrs.get("name") or f"time ({source})"
        return Column("time", groups + [name], el.attrs, direct_time=direct)
    name = _required(el, "name", "")
    labels = None
    if el.tag == "intEnumeration":
        labels = {}
        for option in el.children:
            if option.tag != "option":
                continue
            raw = _required(option, "value", f"in enumeration {name!r} ")
            try:
                labels[int(raw)] = _required(option, "label", f"in enumeration {name!r} ")
            except ValueError as exc:
                raise LogFormatError(
                    f"description.xml: option value {raw!r} of enumeration {name!r} is not an integer."
                ) from exc
    return Column(el.tag, groups + [name], el.attrs, labels=labels)


def _check_archive(zf: zipfile.ZipFile, limits: Limits, size: int) -> None:
    """Declared sizes checked before anything is unpacked (zipfile stops each member at its
    declared size). Members may not share compressed bytes, so the per-member ratio bounds
    the whole: an overlapping-member ZIP bomb is refused here."""
    infos = zf.infolist()
    if sum(i.compress_size for i in infos) > size:
        raise LogFormatError(
            f"The archive's members claim more compressed bytes than its {size} (ZIP bomb?)."
        )
    if len(infos) > limits.max_members:
        raise LogFormatError(
            f"The archive has {len(infos)} members, over the limit of {limits.max_members}."
        )
    total = sum(i.file_size for i in infos)
    if total > limits.max_uncompressed_bytes:
        raise LogFormatError(
            f"The archive would unpack to {total} bytes, over the limit of {limits.max_uncompressed_bytes} (ZIP bomb?)."
        )
    for info in infos:
        ratio = info.file_size / max(info.compress_size, 1)
        if info.file_size > RATIO_FLOOR_BYTES and ratio > limits.max_compression_ratio:
            raise LogFormatError(
                f"The archive member {info.filename!r} is compressed {ratio:.0f}:1, over the limit of "
                f"{limits.max_compression_ratio:.0f}:1 (ZIP bomb?)."
            )


def _parse_column(raw: tuple[str, ...], col: Column, file: str, first_line: int) -> np.ndarray:
    dtype = np.float64 if col.tag == "doubleQuantity" else np.int64
    try:
        return np.array(raw, dtype=dtype)
    except (ValueError, OverflowError):
        for row, text in enumerate(raw, start=first_line):
            try:
                np.array([text], dtype=dtype)
            except (ValueError, OverflowError):
                kind = "a floating-point number" if dtype is np.float64 else "an integer"
                raise LogFormatError(
                    f"{file}, line {row}: value {text!r} of column {'/'.join(col.path)!r} "
                    f"is not {kind}."
                ) from None
        raise


def _check_rows(
    lines: list[str], sep: str, ncols: int, file: str, first_line: int
) -> list[list[str]]:
    rows = [line.split(sep) for line in lines]
    for number, row in enumerate(rows, start=first_line):
        if len(row) != ncols:
            line = lines[number - first_line]
            other = "\t" if sep == "," else ","
            hint = " (is the separator attribute right?)" if len(row) == 1 and other in line else ""
            raise LogFormatError(
                f"{file}, line {number}: {len(row)} values where description.xml describes "
                f"{ncols} columns{hint}."
            )
        if "" in row:
            raise LogFormatError(
                f"{file}, line {number}: empty value in column {row.index('') + 1}."
            )
    return rows


def read_table(
    stream: io.TextIOBase, sep: str, columns: list[Column], file: str
) -> list[np.ndarray]:
    """Parse a value file chunk by chunk, so memory holds arrays plus one chunk of text."""
    ncols = len(columns)
    parts: list[list[np.ndarray]] = [[] for _ in columns]
    line_number = 0
    blank_at = 0  # trailing blank lines are harmless, blank lines between rows are not
    while True:
        chunk = list(itertools.islice(stream, CHUNK_LINES))
        if not chunk:
            break
        lines, first = [], line_number + 1
        for offset, line in enumerate(chunk):
            line = line.rstrip("\r\n")
            if line == "":
                blank_at = blank_at or line_number + offset + 1
                continue
            if blank_at:
                raise LogFormatError(f"{file}, line {blank_at}: empty line between rows.")
            if not lines:
                first = line_number + offset + 1
            lines.append(line)
        line_number += len(chunk)
        if not lines:
            continue
        rows = _check_rows(lines, sep, ncols, file, first)
        for i, (col, values) in enumerate(zip(columns, zip(*rows, strict=True), strict=True)):
            parts[i].append(_parse_column(values, col, file, first))
    return [
        np.concatenate(p)
        if p
        else np.zeros(0, np.float64 if c.tag == "doubleQuantity" else np.int64)
        for p, c in zip(parts, columns, strict=True)
    ]


class DfiImporter:
    name = "DFI"
    extensions = (".dfi", ".zip")

    def sniff(self, path: Path, head: bytes) -> bool:
        # Any ZIP starts with PK\3\4; only claim it when description.xml is a member.
        if not head.startswith(b"PK\x03\x04"):
            return False
        try:
            with zipfile.ZipFile(path) as zf:
                return "description.xml" in zf.namelist()
        except (zipfile.BadZipFile, OSError, NotImplementedError, RuntimeError, ValueError):
            # A damaged or unsupported ZIP (version, method, encryption): ours by name only.
            return path.suffix.lower() == ".dfi"

    def read(self, path: Path, *, limits: Limits, progress: Progress) -> LogData:
        try:
            zf = zipfile.ZipFile(path)
        except zipfile.BadZipFile as exc:
            raise LogFormatError(
                f"The file {path.name!r} is not a ZIP archive (or it is truncated)."
            ) from exc
        with zf:
            _check_archive(zf, limits, path.stat().st_size)
            names = set(zf.namelist())
            if "description.xml" not in names:
                raise LogFormatError("The archive has no description.xml at its root.")
            info = zf.getinfo("description.xml")
            if info.file_size > limits.max_xml_bytes:
                raise LogFormatError(
                    f"description.xml is {info.file_size} bytes, over the limit of {limits.max_xml_bytes}."
                )
            root = parse_xml(self._member(zf, "description.xml"))
            if root.tag != "recording":
                raise LogFormatError(
                    f"description.xml: the document element is <{root.tag}>, not <recording>."
                )
            tops = [el for el in root.children if el.tag == "toplevelgroup"]
            if not tops:
                raise LogFormatError("description.xml describes no <toplevelgroup>.")
            log = LogData(format="dfi")
            seen_files: set[str] = set()
            for number, top in enumerate(tops):
                self._read_top(zf, names, top, seen_files, log)
                progress((number + 1) / len(tops))
        return log

    @staticmethod
    def _member(zf: zipfile.ZipFile, name: str) -> bytes:
        try:
            return zf.read(name)
        except (zipfile.BadZipFile, EOFError, OSError) as exc:
            raise LogFormatError(
                f"The archive member {name!r} is corrupt or truncated: {describe(exc)}."
            ) from exc

    def _read_top(
        self, zf: zipfile.ZipFile, names: set[str], top: Element, seen: set[str], log: LogData
    ) -> None:
        layer = _required(top, "name", "")
        file = _required(top, "file", f"{layer!r} ")
        sep_name = _required(top, "separator", f"{layer!r} ")
        if sep_name not in SEPARATORS:
            raise LogFormatError(
                f"description.xml: unknown separator {sep_name!r} (expected comma or tab)."
            )
        member = posixpath.normpath(file.replace("\\", "/")).lstrip("/")
        if member in seen:
            raise LogFormatError(
                f"description.xml: two toplevelgroups name the same file {file!r}."
            )
        seen.add(member)
        if member not in names:
            raise LogFormatError(
                f"description.xml names the file {file!r}, which is not in the archive."
            )
        columns = _columns(top)
        direct_times = [c for c in columns if c.tag == "time" and c.direct_time]
        if not direct_times:
            raise LogFormatError(f"description.xml: toplevelgroup {layer!r} has no <time> child.")
        try:
            with zf.open(member) as raw_stream:
                text = io.TextIOWrapper(raw_stream, encoding="utf-8", newline="")
                parsed = read_table(text, SEPARATORS[sep_name], columns, file)
        except UnicodeDecodeError as exc:
            raise LogFormatError(f"{file} is not UTF-8 text.") from exc
        except (zipfile.BadZipFile, EOFError, OSError) as exc:
            raise LogFormatError(
                f"The archive member {file!r} is corrupt or truncated: {describe(exc)}."
            ) from exc
        # On-board stamps are the more precise: they become the layer's clock.
        main = next((c for c in direct_times if c.attrs["source"] == "board"), direct_times[0])
        for i, col in enumerate(columns):
            if col.tag == "time":
                parsed[i] = parsed[i] * TIME_UNITS_NS[col.attrs["unit"]]
        _add_series(log, layer, columns, parsed, main)


_KINDS = {
    "intQuantity": "int",
    "doubleQuantity": "double",
    "intEnumeration": "enum",
    "time": "time",
}


def _add_series(
    log: LogData, layer: str, columns: list[Column], parsed: list, main: Column
) -> None:
    """Every column but the clock as a series on the clock's times; a repeated path gets a
    numbered suffix so no column hides another."""
    times = parsed[columns.index(main)]
    source = main.attrs["source"]
    used: set[str] = set()
    for col, arr in zip(columns, parsed, strict=True):
        if col is main:
            continue
        path = join(layer, *col.path)
        base, n = path, 2
        while path in used:
            path, n = f"{base}_{n}", n + 1
        used.add(path)
        unit = "ns" if col.tag == "time" else col.attrs.get("unit", "")
        log.add(
            Series(
                path,
                arr,
                times,
                unit=unit,
                time_source=source,
                kind=_KINDS[col.tag],
                labels=col.labels,
            )  # type: ignore[arg-type]
        )
