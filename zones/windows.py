"""When a zone applies: permanently, or within periods and weekly schedules (UTC).

The stored form (Zone.applicability) is [] for a permanent zone, else a list of periods
{"start": ISO 8601 | None, "end": ISO 8601 | None, "schedule": [{"days": [...],
"start": "HH:MM[:SS]", "end": "HH:MM[:SS]" or "24:00"}]}; a zone applies when any of its
periods does. The periods follow ED-269's `applicability` (permanent, startDateTime,
endDateTime, schedule of days and times) [EUROCAE ED-269]. A daily window whose end is not
after its start runs into the next day, on the days it starts (22:00-02:00 on SAT holds
from Saturday 22:00 to Sunday 02:00; 00:00-00:00 is the whole day), and 24:00 ends a
window at midnight, as aeronautical schedules write them [AIXM 5.1 Timesheet].
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from datetime import UTC, datetime, time
from typing import Any

DAYS = ("MON", "TUE", "WED", "THU", "FRI", "SAT", "SUN")
ANY_DAY = "ANY"
MAX_PERIODS = 50
# HH:MM[:SS[.fraction]], in UTC: a "Z" or a zero offset, or none.
_CLOCK = re.compile(r"^(\d\d):([0-5]\d)(?::([0-5]\d)(?:\.\d+)?)?(?:Z|[+-]00:?00)?$")
END_OF_DAY = "24:00"


class WindowError(ValueError):
    def __init__(self, field: str, message: str) -> None:
        super().__init__(f"{field}: {message}")
        self.field = field
        self.message = message


def instant(value: object, field: str) -> str:
    """An ISO 8601 date-time with its offset, as stored (refused without one: a local
    time in a published file names no instant)."""
    if not isinstance(value, str):
        raise WindowError(field, f"must be an ISO 8601 date-time, got {value!r}")
    try:
        parsed = datetime.fromisoformat(value.replace("Z", "+00:00"))
    except ValueError:
        raise WindowError(field, f"not an ISO 8601 date-time: {value!r}") from None
    if parsed.tzinfo is None:
        raise WindowError(field, f"{value!r} has no time zone")
    return parsed.isoformat()


def clock(value: object, field: str, *, end: bool = False) -> str:
    """A UTC time of day as stored: HH:MM, with :SS when it has seconds (a fraction is
    dropped); 24:00 only where a window ends."""
    match = _CLOCK.match(value) if isinstance(value, str) else None
    hours, minutes, seconds = match.groups() if match else (None, None, None)
    midnight = hours == "24" and minutes == "00" and int(seconds or 0) == 0
    if match is None or (int(hours) > 23 and not (midnight and end)):  # type: ignore[arg-type]
        allowed = "HH:MM[:SS] (00:00 to 24:00)" if end else "HH:MM[:SS] (00:00 to 23:59:59)"
        raise WindowError(field, f"must be a UTC time {allowed}, got {value!r}")
    if midnight:
        return END_OF_DAY
    return f"{hours}:{minutes}" + (f":{seconds}" if seconds and seconds != "00" else "")


def schedule_entry(obj: object, field: str) -> dict:
    if not isinstance(obj, Mapping):
        raise WindowError(field, "must be an object with day, startTime and endTime")
    days = obj.get("day", obj.get("days"))
    days = [days] if isinstance(days, str) else days
    if not isinstance(days, list) or not days:
        raise WindowError(f"{field}.day", "must list days (MON..SUN or ANY)")
    for day in days:
        if day not in (*DAYS, ANY_DAY):
            raise WindowError(f"{field}.day", f"unknown day {day!r}")
    start = clock(obj.get("startTime"), f"{field}.startTime")
    end = clock(obj.get("endTime"), f"{field}.endTime", end=True)
    return {"days": list(days), "start": start, "end": end}


def period(obj: object, field: str) -> dict | None:
    """One ED-269 applicability entry; None for a permanent one."""
    if not isinstance(obj, Mapping):
        raise WindowError(field, "must be an object")
    if str(obj.get("permanent", "NO")).upper() == "YES":
        return None
    start, end = obj.get("startDateTime"), obj.get("endDateTime")
    found = {
        "start": None if start is None else instant(start, f"{field}.startDateTime"),
        "end": None if end is None else instant(end, f"{field}.endDateTime"),
        "schedule": [
            schedule_entry(entry, f"{field}.schedule[{i}]")
            for i, entry in enumerate(_list(obj.get("schedule", []), f"{field}.schedule"))
        ],
    }
    if found["start"] is None and found["end"] is None and not found["schedule"]:
        raise WindowError(field, "not permanent, yet no start, end or schedule")
    if found["start"] and found["end"] and _at(found["start"]) > _at(found["end"]):
        raise WindowError(field, "ends before it starts")
    return found


def applicability(value: Any, field: str) -> list[dict]:
    """The stored form of an ED-269 `applicability` list ([] when any entry is permanent
    or the list is absent)."""
    if value is None:
        return []
    periods = [period(entry, f"{field}[{i}]") for i, entry in enumerate(_list(value, field))]
    return [] if any(p is None for p in periods) else periods  # type: ignore[misc]


def _list(value: object, field: str) -> list:
    if not isinstance(value, list):
        raise WindowError(field, "must be a list")
    if len(value) > MAX_PERIODS:
        raise WindowError(field, f"more than {MAX_PERIODS} entries")
    return value


def _at(text: str) -> datetime:
    return datetime.fromisoformat(text)


def _on(entry: Mapping, weekday: int) -> bool:
    return ANY_DAY in entry["days"] or DAYS[weekday] in entry["days"]


def _in_schedule(entry: Mapping, moment: datetime) -> bool:
    """Within the daily window on one of its days; a window that runs past midnight
    belongs to the day it starts."""
    now = moment.time().replace(microsecond=0)
    start, weekday = time.fromisoformat(entry["start"]), moment.weekday()
    if entry["end"] == END_OF_DAY:
        return now >= start and _on(entry, weekday)
    end = time.fromisoformat(entry["end"])
    if start < end:
        return start <= now <= end and _on(entry, weekday)
    if now >= start:  # the evening part, on its own day
        return _on(entry, weekday)
    return now <= end and _on(entry, (weekday - 1) % 7)  # the morning part, a day later


def applies_at(periods: Sequence[Mapping], moment: datetime) -> bool:
    """Does a zone with these stored periods apply at `moment` (aware)?"""
    if not periods:
        return True
    utc = moment.astimezone(UTC)
    return any(_period_applies(p, utc) for p in periods)


def _period_applies(p: Mapping, moment: datetime) -> bool:
    if p.get("start") and moment < _at(p["start"]):
        return False
    if p.get("end") and moment > _at(p["end"]):
        return False
    schedule = p.get("schedule") or []
    return not schedule or any(_in_schedule(entry, moment) for entry in schedule)


def describe(periods: Sequence[Mapping]) -> str:
    """`permanent`, or the periods in words (for popups and refusals)."""
    if not periods:
        return "permanent"
    return "; ".join(_describe_period(p) for p in periods)


def _describe_period(p: Mapping) -> str:
    parts = []
    if p.get("start") or p.get("end"):
        parts.append(f"{p.get('start') or '…'} to {p.get('end') or '…'}")
    for entry in p.get("schedule") or []:
        parts.append(f"{','.join(entry['days'])} {entry['start']}–{entry['end']} UTC")
    return ", ".join(parts)
