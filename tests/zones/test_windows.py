"""When a published zone applies: ED-269 schedules read as aeronautical schedules are
written [AIXM 5.1 Timesheet]."""

from __future__ import annotations

from datetime import UTC, datetime

import pytest

from zones.windows import WindowError, applicability, applies_at


def periods(*schedule: dict) -> list[dict]:
    return applicability([{"permanent": "NO", "schedule": list(schedule)}], "applicability")


def at(day: int, hour: int, minute: int = 0, second: int = 0) -> datetime:
    """A moment in the week of Monday 2026-12-07 (day 0 Monday ... 6 Sunday), UTC."""
    return datetime(2026, 12, 7 + day, hour, minute, second, tzinfo=UTC)


SATURDAY, SUNDAY, MONDAY = 5, 6, 0


def test_a_window_past_midnight_belongs_to_the_day_it_starts():
    saturday_night = periods({"day": ["SAT"], "startTime": "22:00Z", "endTime": "02:00Z"})
    assert applies_at(saturday_night, at(SATURDAY, 23))
    assert applies_at(saturday_night, at(SUNDAY, 1))
    assert not applies_at(saturday_night, at(SATURDAY, 1))  # Friday's night, not listed
    assert not applies_at(saturday_night, at(SUNDAY, 23))
    assert not applies_at(saturday_night, at(SUNDAY, 2, 1))


def test_midnight_to_midnight_is_the_whole_day_and_24_00_ends_one():
    for end in ("00:00", "24:00", "24:00:00Z"):
        whole = periods({"day": ["SUN"], "startTime": "00:00", "endTime": end})
        assert all(applies_at(whole, at(SUNDAY, hour, 30)) for hour in range(24)), end
        assert not applies_at(whole, at(SATURDAY, 12)), end
        assert not applies_at(whole, at(MONDAY, 0, 30)), end


def test_seconds_and_fractions_are_read_and_the_last_second_kept():
    evening = periods({"day": "ANY", "startTime": "17:00:00.00Z", "endTime": "23:59:59"})
    assert applies_at(evening, at(MONDAY, 23, 59, 59))
    assert not applies_at(evening, at(MONDAY, 16, 59, 59))
    assert evening[0]["schedule"][0] == {"days": ["ANY"], "start": "17:00", "end": "23:59:59"}


@pytest.mark.parametrize(
    ("start", "end"), [("24:00", "02:00"), ("25:00", "26:00"), ("10:00", "24:30"), ("7:00", "8:00")]
)
def test_a_time_of_day_out_of_range_is_refused_with_where(start, end):
    with pytest.raises(WindowError) as refused:
        periods({"day": "MON", "startTime": start, "endTime": end})
    assert refused.value.field.startswith("applicability[0].schedule[0].")
