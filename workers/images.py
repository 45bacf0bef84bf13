"""Opening drone images: only the expected formats, and a pixel limit below Pillow's.

A drone's picture or camera frame is decoded on the ground (thumbnails, checks). A few
kilobytes can declare a huge image (a decompression bomb: a PNG of zeros, a JPEG whose
header claims 30 000 x 30 000 pixels) that would take gigabytes once decoded. Pillow only
refuses beyond ~179 megapixels (`Image.MAX_IMAGE_PIXELS` x 2) and merely warns from ~89;
here the size in the header is checked against MAX_PIXELS before anything is decoded,
without changing Pillow's process-wide limit for the rest of the ground.
"""

from __future__ import annotations

import io
from collections.abc import Iterator, Sequence
from contextlib import contextmanager

from PIL import Image

# 60 megapixels: a 48 MP drone camera (8 064 x 6 048) passes; anything beyond is refused.
MAX_PIXELS = 60_000_000


class ImageRefused(ValueError):
    """An image refused before decoding; `reason` is the counter it is counted under."""

    def __init__(self, reason: str, detail: str) -> None:
        super().__init__(f"{reason}: {detail}")
        self.reason = reason
        self.detail = detail


@contextmanager
def open_image(
    data: bytes, formats: Sequence[str] = ("JPEG",), max_pixels: int = MAX_PIXELS
) -> Iterator[Image.Image]:
    """The image, opened lazily (nothing decoded yet) once its format is one of `formats`
    and its declared size is within `max_pixels`; else ImageRefused (`too_many_pixels`,
    `unreadable_picture`)."""
    try:
        image = Image.open(io.BytesIO(data), formats=list(formats))
    except Image.DecompressionBombError as exc:
        raise ImageRefused("too_many_pixels", str(exc)) from None
    except (OSError, ValueError, SyntaxError) as exc:
        raise ImageRefused("unreadable_picture", str(exc)) from None
    with image:
        width, height = image.size
        if width * height > max_pixels:
            raise ImageRefused(
                "too_many_pixels", f"{width} x {height} pixels, more than {max_pixels}"
            )
        yield image
