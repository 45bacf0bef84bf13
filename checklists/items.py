"""What a checklist template may hold, checked before anything is stored.

A template is a name, a validity in minutes and a list of items. An item is either
`{"kind": "manual", "text": ...}`, which a person confirms, or `{"kind": "auto",
"check": ..., "threshold": ...}`, which the platform measures from live data
(checklists/checks.py). Every refusal names the field it is about (`items[2].check`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from django.conf import settings

MANUAL = "manual"
AUTO = "auto"
MAX_TEXT = 200
MAX_NAME = 120
MAX_VALID_MINUTES = 24 * 60


@dataclass(frozen=True)
class Check:
    """An automatic item: what it measures and, when it has one, its threshold's range."""

    label: str
    unit: str = ""
    default: float | None = None
    low: float = 0.0
    high: float = 0.0
    whole: bool = False

    @property
    def has_threshold(self) -> bool:
        return self.default is not None


# The automatic items. The GPS default is PX4's minimum for GPS use [PX4 EKF2].
CHECKS: dict[str, Check] = {
    "gps": Check("3D GPS fix with at least this many satellites", "satellites", 6, 4, 40, True),
    "battery": Check("battery charge at least", "fraction of full", 0.8, 0.05, 1.0),
    "link": Check("drone and flight controller linked, last heartbeat within", "s", 15, 1, 600),
    "envelope": Check("envelope in force: home known, position inside the geofence"),
    "zones": Check("no published zone refuses a take-off here to", "m", 10, 1, 120),
    "remote_id": Check("Remote ID healthy"),
    "wind": Check("wind within the drone's limit (its flight controller's estimate)"),
    "airworthy": Check("airworthy: no maintenance due, no retired battery, Remote ID"),
}


class ChecklistError(Exception):
    """Bad input: `field` names what is wrong; nothing was changed."""

    def __init__(self, field: str, message: str) -> None:
        super().__init__(f"{field}: {message}")
        self.field = field
        self.message = message


def _text(value: Any, field: str, limit: int) -> str:
    if not isinstance(value, str) or not value.strip():
        raise ChecklistError(field, "must be a non-empty string")
    if len(value) > limit:
        raise ChecklistError(field, f"must be at most {limit} characters")
    return value.strip()


def _number(value: Any, field: str, low: float, high: float, whole: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise ChecklistError(field, "must be a number")
    if whole and value != int(value):
        raise ChecklistError(field, "must be a whole number")
    if not low <= value <= high:
        raise ChecklistError(field, f"must be between {low:g} and {high:g}")
    return int(value) if whole else float(value)


def _only(item: Mapping, allowed: set[str], field: str) -> None:
    unknown = sorted(set(item) - allowed)
    if unknown:
        raise ChecklistError(f"{field}.{unknown[0]}" if field else unknown[0], "unknown field")


def clean_item(item: Any, field: str) -> dict:
    """One item, with an automatic item's threshold filled in from its default."""
    if not isinstance(item, Mapping):
        raise ChecklistError(field, "must be an object")
    kind = item.get("kind")
    if kind == MANUAL:
        _only(item, {"kind", "text"}, field)
        return {"kind": MANUAL, "text": _text(item.get("text"), f"{field}.text", MAX_TEXT)}
    if kind != AUTO:
        raise ChecklistError(f"{field}.kind", f"must be {MANUAL!r} or {AUTO!r}")
    _only(item, {"kind", "check", "threshold"}, field)
    name = item.get("check")
    check = CHECKS.get(name) if isinstance(name, str) else None
    if check is None:
        raise ChecklistError(f"{field}.check", f"unknown automatic item; one of {sorted(CHECKS)}")
    if not check.has_threshold:
        if item.get("threshold") is not None:
            raise ChecklistError(f"{field}.threshold", f"{name} takes no threshold")
        return {"kind": AUTO, "check": name, "threshold": None}
    raw = item.get("threshold", check.default)
    threshold = _number(raw, f"{field}.threshold", check.low, check.high, check.whole)
    return {"kind": AUTO, "check": name, "threshold": threshold}


def clean_items(items: Any) -> list[dict]:
    if not isinstance(items, list) or not items:
        raise ChecklistError("items", "must be a non-empty list")
    if len(items) > settings.CHECKLIST_MAX_ITEMS:
        raise ChecklistError("items", f"at most {settings.CHECKLIST_MAX_ITEMS} items")
    return [clean_item(item, f"items[{i}]") for i, item in enumerate(items)]


def clean_valid_minutes(value: Any, field: str = "valid_minutes") -> int:
    return int(_number(value, field, 1, MAX_VALID_MINUTES, whole=True))


def clean_template(data: Any, *, default_valid_minutes: int) -> dict:
    """`name`, `items` and `valid_minutes` (the organisation's when left out)."""
    if not isinstance(data, Mapping):
        raise ChecklistError("body", "must be a JSON object")
    _only(data, {"name", "items", "valid_minutes"}, "")
    return {
        "name": _text(data.get("name"), "name", MAX_NAME),
        "items": clean_items(data.get("items")),
        "valid_minutes": clean_valid_minutes(data.get("valid_minutes", default_valid_minutes)),
    }


def clean_answers(items: list[dict], answers: Any) -> list[bool]:
    """One true/false per manual item, in the template's order."""
    manual = sum(1 for item in items if item["kind"] == MANUAL)
    if not isinstance(answers, list) or len(answers) != manual:
        raise ChecklistError("answers", f"must be a list of {manual} true/false values")
    for i, answer in enumerate(answers):
        if not isinstance(answer, bool):
            raise ChecklistError(f"answers[{i}]", "must be true or false")
    return list(answers)
