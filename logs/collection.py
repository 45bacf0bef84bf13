"""Logs the drones upload by themselves after landing: offered, received in chunks at
increasing offsets, stored exactly once, and imported like any uploaded log.

The contract (docs/protocol.md, "Logs collected by themselves"): the drone offers a log
with its kind, name, size, SHA-256 and flight span; the ground answers how many bytes it
already holds. Chunks then come at that offset; a chunk at any other offset changes
nothing and is answered with the offset expected, so a drone that lost its link resumes
where the ground is. One drone's log of one kind with the same bytes is one row (the
idempotency key: drone, kind, content hash), so an offer repeated after the log was
stored is answered `stored` and nothing is stored twice. The last chunk is checked
against the hash before the log becomes a FlightLog.
"""

from __future__ import annotations

import hashlib
import os
import re
from dataclasses import dataclass
from datetime import datetime, timedelta

from django.conf import settings
from django.db import IntegrityError, transaction
from django.db.models import Q, QuerySet
from django.utils import timezone

from fleet.models import Drone
from logs import services
from logs.importers import HEAD_BYTES, pick_importer
from logs.importers.base import LogFormatError
from logs.models import CollectedLog, CollectedLogKind
from logs.uploads import StoredUpload

SHA256_RE = re.compile(r"^[0-9a-f]{64}$")
HASH_BLOCK = 1024 * 1024


class CollectionRefused(Exception):
    """An offer or chunk that cannot be taken; `code` for the API, `status` its HTTP status."""

    def __init__(self, code: str, message: str, status: int = 400, received: int | None = None):
        super().__init__(message)
        self.code = code
        self.message = message
        self.status = status
        self.received = received


@dataclass(frozen=True)
class Offer:
    kind: str
    name: str
    size: int
    sha256: str
    flight_started_at: datetime
    flight_ended_at: datetime


def check_offer(offer: Offer) -> None:
    """Refuse what the ground would never store: unknown kind, bad hash, empty or too big."""
    if offer.kind not in CollectedLogKind.values:
        raise CollectionRefused("bad_kind", f"Unknown log kind {offer.kind!r}.")
    if not SHA256_RE.match(offer.sha256):
        raise CollectionRefused("bad_hash", "sha256 must be 64 lower-case hex digits.")
    if offer.size <= 0:
        raise CollectionRefused("empty", "The log is empty.")
    if offer.size > int(settings.LOG_COLLECT_MAX_BYTES):
        raise CollectionRefused(
            "too_large",
            f"The log is larger than the collection limit of {settings.LOG_COLLECT_MAX_BYTES} "
            "bytes.",
            status=413,
        )
    if offer.flight_ended_at < offer.flight_started_at:
        raise CollectionRefused("bad_flight", "The flight ends before it starts.")


def offer(drone: Drone, wanted: Offer) -> CollectedLog:
    """The row for this log: the one stored or under way, else a new one (within the
    drone's LOG_COLLECT_MAX_OPEN unfinished uploads)."""
    check_offer(wanted)
    existing = _existing(drone, wanted)
    if existing is not None:
        return existing
    forget_abandoned(drone)
    unfinished = CollectedLog.objects.filter(drone=drone, completed_at__isnull=True).count()
    if unfinished >= int(settings.LOG_COLLECT_MAX_OPEN):
        raise CollectionRefused(
            "too_many_open",
            f"This drone has {unfinished} unfinished log uploads; finish one first.",
            status=429,
        )
    try:
        with transaction.atomic():
            return CollectedLog.objects.create(
                organisation_id=drone.organisation_id,
                drone=drone,
                kind=wanted.kind,
                name=os.path.basename(wanted.name)[:255] or "log",
                size=wanted.size,
                sha256=wanted.sha256,
                flight_started_at=wanted.flight_started_at,
                flight_ended_at=wanted.flight_ended_at,
            )
    except IntegrityError:  # offered at the same moment on another connection
        found = _existing(drone, wanted)
        assert found is not None
        return found


def forget_abandoned(drone: Drone) -> int:
    """Drop the drone's uploads unfinished for LOG_COLLECT_ABANDONED_S and their bytes (the
    drone lost the file, or its disk): they no longer hold a place of LOG_COLLECT_MAX_OPEN."""
    before = timezone.now() - timedelta(seconds=float(settings.LOG_COLLECT_ABANDONED_S))
    stale = list(
        CollectedLog.objects.filter(drone=drone, completed_at__isnull=True, created_at__lt=before)
    )
    for row in stale:
        row.part_path.unlink(missing_ok=True)
        row.delete()
    return len(stale)


def _existing(drone: Drone, wanted: Offer) -> CollectedLog | None:
    found = CollectedLog.objects.filter(drone=drone, kind=wanted.kind, sha256=wanted.sha256).first()
    if found is not None and found.size != wanted.size:
        raise CollectionRefused(
            "size_mismatch", "This log was offered before with another size.", status=409
        )
    return found


def receive(drone: Drone, upload_id: str, offset: int, data: bytes) -> CollectedLog:
    """Append `data` at `offset` (the bytes held so far); the last chunk completes it."""
    if len(data) > int(settings.LOG_COLLECT_CHUNK_MAX_BYTES):
        raise CollectionRefused(
            "chunk_too_large",
            f"A chunk holds at most {settings.LOG_COLLECT_CHUNK_MAX_BYTES} bytes.",
            status=413,
        )
    with transaction.atomic():
        # The row lock orders a drone's concurrent chunks of one log: one appends at a time.
        row = CollectedLog.objects.select_for_update().filter(pk=upload_id, drone=drone).first()
        if row is None:
            raise CollectionRefused("not_found", "No such upload of this drone.", status=404)
        if row.completed_at is not None:
            return row
        if offset != row.received or not data or offset + len(data) > row.size:
            raise CollectionRefused(
                "bad_offset",
                f"Expected a chunk at offset {row.received} within {row.size} bytes.",
                status=409,
                received=row.received,
            )
        _append(row, offset, data)
        row.received = offset + len(data)
        CollectedLog.objects.filter(pk=row.pk).update(received=row.received)
        refusal = _complete(row) if row.received == row.size else None
    if refusal is not None:  # raised once the reset to 0 is committed
        raise refusal
    return row


def _append(row: CollectedLog, offset: int, data: bytes) -> None:
    """Write at `offset` (not at the end): a part file longer than the row says, left by
    a write whose transaction did not commit, is overwritten rather than kept."""
    path = row.part_path
    path.parent.mkdir(parents=True, exist_ok=True)
    mode = "r+b" if path.exists() else "wb"
    with open(path, mode) as f:
        f.seek(offset)
        f.write(data)
        f.truncate()
        f.flush()
        os.fsync(f.fileno())


def _digest(path) -> str:  # type: ignore[no-untyped-def]
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        while block := f.read(HASH_BLOCK):
            digest.update(block)
    return digest.hexdigest()


def _restart(row: CollectedLog, code: str, message: str, status: int) -> CollectionRefused:
    """Discard the bytes received and say why: the drone sends the log again from 0."""
    row.part_path.unlink(missing_ok=True)
    row.received = 0
    CollectedLog.objects.filter(pk=row.pk).update(received=0)
    return CollectionRefused(code, message, status=status, received=0)


def _complete(row: CollectedLog) -> CollectionRefused | None:
    """Check the bytes against the offered hash and format, then make them a FlightLog
    (the import and its checks are queued on commit) attached to this row; a refusal
    when they fail (the bytes are discarded)."""
    path = row.part_path
    if _digest(path) != row.sha256:
        return _restart(row, "hash_mismatch", "The bytes do not match the offered SHA-256.", 422)
    with open(path, "rb") as f:
        head = f.read(HEAD_BYTES)
    try:
        pick_importer(path.with_name(row.name), head)
    except LogFormatError as exc:
        return _restart(row, "unsupported_format", str(exc), 422)
    upload = StoredUpload(path, row.name, row.size, "application/octet-stream")
    log = services.create_log(organisation=row.organisation, owner=None, upload=upload)
    _place(log, row)
    row.log = log
    row.completed_at = timezone.now()
    CollectedLog.objects.filter(pk=row.pk).update(log=log, completed_at=row.completed_at)
    return None


def _place(log, row: CollectedLog) -> None:  # type: ignore[no-untyped-def]
    """The log's drone and flight time, for the drone's history of logs."""
    fields = {f.name for f in log._meta.get_fields()}
    changes = {}
    if "drone" in fields:
        changes["drone"] = row.drone
    if "flown_at" in fields:
        changes["flown_at"] = row.flight_started_at
    if changes:
        type(log).objects.filter(pk=log.pk).update(**changes)


def logs_of_flight(
    drone_id: int | None, started_at: datetime, ended_at: datetime
) -> QuerySet[CollectedLog]:
    """The collected logs whose flight overlaps [started_at, ended_at] (within
    LOG_COLLECT_ATTACH_MARGIN_S for the drone's clock), stored ones only."""
    if drone_id is None:
        return CollectedLog.objects.none()
    margin = timedelta(seconds=float(settings.LOG_COLLECT_ATTACH_MARGIN_S))
    return (
        CollectedLog.objects.filter(drone_id=drone_id, log__isnull=False)
        .filter(
            Q(flight_started_at__lte=ended_at + margin)
            & Q(flight_ended_at__gte=started_at - margin)
        )
        .select_related("log")
    )


def describe(row: CollectedLog) -> dict:
    """What the drone is told about its upload (and what a record lists)."""
    return {
        "id": str(row.pk),
        "kind": row.kind,
        "name": row.name,
        "size": row.size,
        "received": row.received,
        "status": "stored" if row.completed_at is not None else "receiving",
        "log": str(row.log_id) if row.log_id else None,
    }
