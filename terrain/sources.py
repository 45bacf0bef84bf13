"""The elevation files of what an operator imports: one file, a folder of them, or a ZIP.

NASA and USGS ship SRTM tiles one per ZIP (N38W010.SRTMGL1.hgt.zip), so a folder may hold
ZIPs too; a ZIP inside a ZIP is not opened. What an import may cost is bounded (`Limits`,
from the settings): at most TERRAIN_IMPORT_MAX_FILES files of at most
TERRAIN_FILE_MAX_BYTES each, TERRAIN_IMPORT_MAX_BYTES in all, each grid at most
TERRAIN_MAX_SAMPLES samples. A ZIP's member count, declared sizes and compression ratios
are checked before one byte is unpacked; before that, the size of its central directory
(`zipfile` builds an object per entry it lists), so a ZIP of millions of empty entries
costs nothing.
"""

from __future__ import annotations

import struct
import zipfile
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from django.conf import settings

from terrain.formats import HGT_NAME, TerrainError

DEM_SUFFIXES = (".hgt", ".tif", ".tiff")
# A member unpacking to more than this many times its packed size is refused as a
# decompression bomb. Elevations compress well (a tile of sea is one value), up to
# Deflate's own ceiling of about 1032:1 (RFC 1951: 258 bytes per 2-bit code at best), so
# the bound sits above it: only other methods (bzip2, LZMA) reach beyond. The declared
# sizes, checked first, bound what any member may unpack to.
MAX_ZIP_RATIO = 2000
# Members a ZIP may hold per allowed file (folders, readme files beside the tiles), and
# the central directory bytes each may take (46 fixed bytes, its name and extra fields).
MEMBERS_PER_FILE = 4
DIRECTORY_BYTES_PER_MEMBER = 1024
# ZIP records (APPNOTE.TXT 6.3, sections 4.3.14–4.3.16): the end of central directory
# record (22 bytes, then a comment of up to 65535), the ZIP64 locator before it.
END_OF_DIRECTORY, ZIP64_LOCATOR, END_HEAD, LOCATOR_HEAD = b"PK\x05\x06", b"PK\x06\x07", 22, 20

Member = tuple[str, bytes]


@dataclass(frozen=True)
class Limits:
    files: int
    total_bytes: int
    file_bytes: int
    samples: int

    @classmethod
    def from_settings(cls) -> Limits:
        return cls(
            int(settings.TERRAIN_IMPORT_MAX_FILES),
            int(settings.TERRAIN_IMPORT_MAX_BYTES),
            int(settings.TERRAIN_FILE_MAX_BYTES),
            int(settings.TERRAIN_MAX_SAMPLES),
        )

    def check_count(self, count: int) -> None:
        if count > self.files:
            raise TerrainError(f"more than {self.files} elevation files, the limit (TERRAIN_IMPORT_MAX_FILES); nothing was imported")  # fmt: skip

    def check_file(self, name: str, size: int) -> None:
        if size > self.file_bytes:
            raise TerrainError(f"{name} is larger than {self.file_bytes} bytes, the limit for one file (TERRAIN_FILE_MAX_BYTES); nothing was imported")  # fmt: skip

    def check_total(self, total: int) -> None:
        if total > self.total_bytes:
            raise TerrainError(f"the files add up to more than {self.total_bytes} bytes, the limit (TERRAIN_IMPORT_MAX_BYTES); nothing was imported")  # fmt: skip


def is_dem_name(name: str) -> bool:
    base = name.rsplit("/", 1)[-1]
    return not base.startswith(".") and (
        bool(HGT_NAME.match(base)) or base.lower().endswith(DEM_SUFFIXES)
    )


def dem_files(path: Path, limits: Limits) -> Iterator[Member]:
    """(name, bytes) of every elevation file in `path`: a file, a folder or a ZIP."""
    if path.is_dir():
        yield from _folder(path, limits)
    elif not path.is_file():
        raise TerrainError(f"{path} is neither a file nor a folder")
    elif zipfile.is_zipfile(path):
        yield from _zip(path, limits)
    else:
        limits.check_file(path.name, path.stat().st_size)
        yield path.name, path.read_bytes()


def _folder(folder: Path, limits: Limits) -> Iterator[Member]:
    for path in sorted(p for p in folder.rglob("*") if p.is_file()):
        name = path.relative_to(folder).as_posix()
        if path.suffix.lower() == ".zip":
            yield from ((f"{name}/{member}", data) for member, data in _zip(path, limits))
        elif is_dem_name(name):
            limits.check_file(name, path.stat().st_size)
            yield name, path.read_bytes()


def central_directory_size(path: Path) -> int:
    """The size its end record declares for the ZIP's central directory (ZIP64 too)."""
    with path.open("rb") as f:
        end = f.seek(0, 2)
        tail_at = max(0, end - END_HEAD - 65535)
        f.seek(tail_at)
        tail = f.read()
        found = tail.rfind(END_OF_DIRECTORY)
        if found < 0 or len(tail) - found < END_HEAD:
            raise TerrainError(f"{path.name} is not a ZIP archive (no end of central directory)")
        size = struct.unpack("<I", tail[found + 12 : found + 16])[0]
        locator = tail[max(0, found - LOCATOR_HEAD) : found]
        if locator.startswith(ZIP64_LOCATOR):
            f.seek(struct.unpack("<Q", locator[8:16])[0])
            record = f.read(56)
            size = struct.unpack("<Q", record[40:48])[0] if len(record) == 56 else size
    return size


def _zip(path: Path, limits: Limits) -> Iterator[Member]:
    members = limits.files * MEMBERS_PER_FILE
    if central_directory_size(path) > members * DIRECTORY_BYTES_PER_MEMBER:
        raise TerrainError(f"{path.name} lists more than {members} members, the limit (TERRAIN_IMPORT_MAX_FILES x {MEMBERS_PER_FILE}); nothing was imported")  # fmt: skip
    try:
        with zipfile.ZipFile(path) as archive:
            listed = archive.infolist()
            if len(listed) > limits.files * MEMBERS_PER_FILE:
                raise TerrainError(f"{path.name} holds {len(listed)} members, more than the limit (TERRAIN_IMPORT_MAX_FILES x {MEMBERS_PER_FILE}); nothing was imported")  # fmt: skip
            members = [i for i in listed if not i.is_dir() and is_dem_name(i.filename)]
            check_zip_members(path.name, members, limits)
            for info in members:
                # zipfile stops at the declared size, which was checked above.
                with archive.open(info) as member:
                    yield info.filename, member.read(limits.file_bytes + 1)
    except (zipfile.BadZipFile, OSError, EOFError) as exc:
        raise TerrainError(f"{path.name} is not a readable ZIP archive ({exc})") from None


def check_zip_members(name: str, infos: list[zipfile.ZipInfo], limits: Limits) -> None:
    """Every declared size and ratio, and their sum, before one byte is unpacked."""
    limits.check_count(len(infos))
    for info in infos:
        limits.check_file(info.filename, info.file_size)
        if info.file_size > MAX_ZIP_RATIO * max(info.compress_size, 1):
            raise TerrainError(f"{name}: {info.filename} unpacks to more than {MAX_ZIP_RATIO} times its packed size (a ZIP bomb); nothing was imported")  # fmt: skip
    limits.check_total(sum(info.file_size for info in infos))
