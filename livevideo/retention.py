"""How long recorded video is kept: each organisation's period and size cap
(VideoRetention), or the platform's LIVE_VIDEO_RECORDING_KEEP_DAYS and
LIVE_VIDEO_RECORDINGS_MAX_BYTES_PER_ORG where it chose none. Past its period a recording
goes; beyond its cap the organisation's oldest go first."""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime, timedelta

from django.conf import settings
from django.db.models import Sum
from django.utils import timezone

from fleet.models import Organisation

from .models import VideoRecording, VideoRetention

# Bounds on what an organisation may choose: a day to ten years; 1 MiB to 10 TiB.
KEEP_DAYS_RANGE = (1, 3650)
MAX_BYTES_RANGE = (1 << 20, 10 << 40)


@dataclass(frozen=True)
class Rule:
    keep_days: int
    max_bytes: int
    chosen: bool  # the organisation set one of them itself


class RetentionError(ValueError):
    def __init__(self, field: str, message: str) -> None:
        super().__init__(message)
        self.field, self.message = field, message


def rule_for(organisation: Organisation) -> Rule:
    row = VideoRetention.objects.filter(organisation=organisation).first()
    return _rule(row)


def _rule(row: VideoRetention | None) -> Rule:
    keep = row.keep_days if row and row.keep_days is not None else None
    cap = row.max_bytes if row and row.max_bytes is not None else None
    return Rule(
        keep_days=keep if keep is not None else settings.LIVE_VIDEO_RECORDING_KEEP_DAYS,
        max_bytes=cap if cap is not None else settings.LIVE_VIDEO_RECORDINGS_MAX_BYTES_PER_ORG,
        chosen=keep is not None or cap is not None,
    )


def describe(organisation: Organisation) -> dict:
    rule = rule_for(organisation)
    used = VideoRecording.objects.filter(drone__organisation=organisation).aggregate(
        total=Sum("size")
    )["total"]
    return {
        "organisation": organisation.slug,
        "keep_days": rule.keep_days,
        "max_bytes": rule.max_bytes,
        "own_rule": rule.chosen,
        "used_bytes": used or 0,
    }


def _bounded(data: dict, field: str, bounds: tuple[int, int]) -> int | None:
    value = data.get(field)
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int):
        raise RetentionError(field, "A whole number, or null for the platform's setting.")
    low, high = bounds
    if not low <= value <= high:
        raise RetentionError(field, f"Between {low} and {high}.")
    return value


def set_rule(organisation: Organisation, data: dict) -> dict:
    """Set the organisation's period and cap (null: the platform's); every field is
    checked before anything is written."""
    if not isinstance(data, dict):
        raise RetentionError("non_field_errors", "A JSON object.")
    unknown = set(data) - {"keep_days", "max_bytes"}
    if unknown:
        raise RetentionError(sorted(unknown)[0], "Unknown field.")
    keep = _bounded(data, "keep_days", KEEP_DAYS_RANGE)
    cap = _bounded(data, "max_bytes", MAX_BYTES_RANGE)
    VideoRetention.objects.update_or_create(
        organisation=organisation, defaults={"keep_days": keep, "max_bytes": cap}
    )
    return describe(organisation)


def _delete(rows: list[VideoRecording]) -> int:
    for row in rows:
        row.file.delete(save=False)
        row.delete()
    return len(rows)


def _prune_organisation(organisation_id: int, rule: Rule, now: datetime) -> int:
    mine = VideoRecording.objects.filter(drone__organisation_id=organisation_id)
    cutoff = now - timedelta(days=rule.keep_days)
    deleted = _delete(list(mine.filter(ended_at__lt=cutoff)))
    excess = (mine.aggregate(total=Sum("size"))["total"] or 0) - rule.max_bytes
    doomed = []
    for row in mine.order_by("started_at", "id").iterator():
        if excess <= 0:
            break
        doomed.append(row)
        excess -= row.size
    return deleted + _delete(doomed)


def prune(now: datetime | None = None) -> int:
    """Delete what each organisation's rule says is past keeping; the number deleted."""
    now = now or timezone.now()
    chosen = {r.organisation_id: r for r in VideoRetention.objects.all()}
    holders = (
        VideoRecording.objects.values_list("drone__organisation_id", flat=True)
        .order_by()
        .distinct()
    )
    return sum(
        _prune_organisation(org_id, _rule(chosen.get(org_id)), now) for org_id in list(holders)
    )
