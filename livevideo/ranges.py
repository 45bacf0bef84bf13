"""One byte range of a recording (RFC 9110 §14): what a browser's video element asks for
to seek in a file, which Django's FileResponse does not answer by itself.

Only a single range is served (`bytes=a-b`, `bytes=a-`, `bytes=-n`); a list of ranges
or a malformed header gets the whole file (§14.2 lets a server ignore Range), and a range
past the end gets 416 with the file's size, as the RFC says.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

RANGE_RE = re.compile(r"^bytes=(?P<first>\d{0,19})-(?P<last>\d{0,19})$")


class Unsatisfiable(ValueError):
    pass


@dataclass(frozen=True)
class ByteRange:
    first: int
    last: int  # inclusive

    @property
    def length(self) -> int:
        return self.last - self.first + 1

    def content_range(self, size: int) -> str:
        return f"bytes {self.first}-{self.last}/{size}"


def parse(header: str | None, size: int) -> ByteRange | None:
    """The range a `Range` header asks of a `size`-byte file; None for the whole file;
    Unsatisfiable when it starts past the end (or the file is empty)."""
    match = RANGE_RE.match((header or "").strip())
    if match is None:
        return None
    first, last = match["first"], match["last"]
    if not first and not last:
        return None
    if not first:  # the last n bytes
        n = int(last)
        if n == 0 or size == 0:
            raise Unsatisfiable(header)
        return ByteRange(max(0, size - n), size - 1)
    start = int(first)
    end = min(int(last), size - 1) if last else size - 1
    if start >= size:
        raise Unsatisfiable(header)
    if end < start:
        return None
    return ByteRange(start, end)
