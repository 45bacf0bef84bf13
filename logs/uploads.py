"""Streaming a log upload straight into the logs folder, refusing it past the size limit.

Django's own handlers would first keep up to FILE_UPLOAD_MAX_MEMORY_SIZE in memory, then
write to a temporary file that the view copies again; this handler writes each chunk to
its final folder at once and stops reading as soon as the upload is over the limit.
"""

from __future__ import annotations

import logging
import os
import time
import uuid
from pathlib import Path

from django.conf import settings
from django.core.files.uploadedfile import UploadedFile
from django.core.files.uploadhandler import FileUploadHandler, SkipFile
from django.http import HttpRequest
from rest_framework import status
from rest_framework.exceptions import APIException

logger = logging.getLogger(__name__)

FIELD = "file"
# Multipart headers and boundaries around the file add a little to Content-Length.
MULTIPART_SLACK_BYTES = 64 * 1024


class UploadTooLarge(APIException):
    status_code = status.HTTP_413_REQUEST_ENTITY_TOO_LARGE
    default_code = "too_large"

    def __init__(self, limit: int) -> None:
        super().__init__(
            f"The file is larger than the upload limit of {human_bytes(limit)}.", "too_large"
        )


def human_bytes(n: float) -> str:
    for unit in ("bytes", "KB", "MB", "GB"):
        if n < 1024 or unit == "GB":
            return f"{n:.0f} {unit}" if unit == "bytes" else f"{n:.1f} {unit}"
        n /= 1024
    return f"{n:.1f} GB"


def upload_limit() -> int:
    return int(settings.LOG_UPLOAD_MAX_BYTES)


def incoming_dir() -> Path:
    path = Path(settings.LOGS_DIR) / "incoming"
    path.mkdir(parents=True, exist_ok=True)
    return path


# A `.part` file this old belongs to an upload whose connection died mid-body (the parser
# never got to tell the handler); live uploads touch theirs with every chunk.
STALE_PART_S = 24 * 3600


def sweep_stale_parts(directory: Path, *, now: float | None = None) -> int:
    """Delete abandoned partial uploads; returns how many went."""
    now = time.time() if now is None else now
    removed = 0
    for part in directory.glob("*.part"):
        try:
            if now - part.stat().st_mtime > STALE_PART_S:
                part.unlink()
                removed += 1
        except FileNotFoundError:
            continue  # finished or swept by a concurrent upload
    if removed:
        logger.info("removed %d abandoned partial uploads from %s", removed, directory)
    return removed


def check_content_length(request: HttpRequest) -> None:
    """Refuse before a byte of the body is parsed when the client announces too much."""
    try:
        length = int(request.META.get("CONTENT_LENGTH") or 0)
    except ValueError:
        length = 0
    if length > upload_limit() + MULTIPART_SLACK_BYTES:
        raise UploadTooLarge(upload_limit())


class StoredUpload(UploadedFile):
    """An uploaded file already on disk at `path` (moved into place by the caller)."""

    def __init__(self, path: Path, name: str, size: int, content_type: str | None) -> None:
        super().__init__(None, name, content_type, size)
        self.path = path

    def temporary_file_path(self) -> str:
        return str(self.path)

    def discard(self) -> None:
        self.path.unlink(missing_ok=True)


class LogUploadHandler(FileUploadHandler):
    """Writes the `file` field to LOGS_DIR/incoming, aborting past LOG_UPLOAD_MAX_BYTES."""

    chunk_size = 1024 * 1024

    def __init__(self, request: HttpRequest | None = None) -> None:
        super().__init__(request)
        self.limit = upload_limit()
        self._file = None
        self._path: Path | None = None
        self._written = 0

    def handle_raw_input(self, input_data, META, content_length, boundary, encoding=None):  # type: ignore[no-untyped-def]  # noqa: N803
        if content_length and content_length > self.limit + MULTIPART_SLACK_BYTES:
            raise UploadTooLarge(self.limit)

    def new_file(
        self,
        field_name,
        file_name,
        content_type,
        content_length,
        charset=None,
        content_type_extra=None,
    ):  # type: ignore[no-untyped-def]
        if field_name != FIELD or self._path is not None:
            raise SkipFile()  # one log per request; other file fields are not read
        super().new_file(field_name, file_name, content_type, content_length, charset)
        directory = incoming_dir()
        sweep_stale_parts(directory)
        self._path = directory / f"{uuid.uuid4().hex}.part"
        self._file = open(self._path, "wb")  # noqa: SIM115 - closed in file_complete/abort

    def receive_data_chunk(self, raw_data: bytes, start: int) -> bytes | None:
        if self._file is None:
            return raw_data
        self._written += len(raw_data)
        if self._written > self.limit:
            self._abort()
            raise UploadTooLarge(self.limit)
        self._file.write(raw_data)
        return None

    def file_complete(self, file_size: int) -> UploadedFile | None:
        if self._file is None or self._path is None:
            return None
        self._file.close()
        self._file = None
        return StoredUpload(self._path, self.file_name, file_size, self.content_type)

    def upload_interrupted(self) -> None:
        self._abort()

    def _abort(self) -> None:
        if self._file is not None:
            self._file.close()
            self._file = None
        if self._path is not None:
            try:
                os.unlink(self._path)
            except FileNotFoundError:
                pass


def install(request: HttpRequest) -> None:
    """Replace the request's upload handlers; call before anything reads request.POST."""
    request.upload_handlers = [LogUploadHandler(request)]
