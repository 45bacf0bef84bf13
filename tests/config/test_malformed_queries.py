"""Malformed query parameters answer 4xx, never 500, on every page and API resource.

Walks every URL pattern of the portal and the API as a signed-in operator, each with
every query parameter a view reads (found in the source, plus the serializer-read ones
below) set to one malformed value at a time: ids as text, huge numbers, NUL bytes,
negatives, bad dates, non-finite numbers."""

from __future__ import annotations

import re
import uuid
from pathlib import Path

import pytest
from django.test import Client
from django.urls import URLPattern, URLResolver, get_resolver, resolve
from django.urls.exceptions import Resolver404

ROOT = Path(__file__).resolve().parents[2]
# Every app of the project, and the project's own package.
APPS = ("config", *sorted(p.parent.name for p in ROOT.glob("*/apps.py")))
READ = re.compile(r"""(?:GET|query_params)\.(?:get|getlist)\(\s*["']([A-Za-z_]+)["']""")
# Read through serializers or helpers rather than `.get("…")` in a view.
ALSO_READ = (
    "page",
    "page_size",
    "object",
    "fields",
    "start",
    "end",
    "points",
    "source",
    "layout",
    "format",
    "limit",
    "bins",
    "ids",
    "pick",
    # The flight filters (records.logbook), read from the query by name.
    "drone",
    "pilot",
    "mission",
    "since",
    "until",
)
MALFORMED = (
    "x",
    "99999999999999999999999999",
    "\x00",
    "-1",
    "2026-13-45T99:99",
    "nan",
    "1e309",
    "ACME_1\x00",
)
# Pages whose GET ends the session or streams without end are not walked.
SKIP = re.compile(r"logout|/ws/|events/stream|/sse")


def parameter_names() -> list[str]:
    names = set(ALSO_READ)
    for app in APPS:
        for source in (ROOT / app).rglob("*.py"):
            names.update(READ.findall(source.read_text(errors="replace")))
    return sorted(names)


def _leaves(patterns, prefix: str = ""):  # type: ignore[no-untyped-def]
    for entry in patterns:
        route = prefix + str(entry.pattern)
        if isinstance(entry, URLResolver):
            yield from _leaves(entry.url_patterns, route)
        elif isinstance(entry, URLPattern):
            yield route


def _path(route: str, ids: dict[str, str]) -> str | None:
    """A concrete path for a pattern, its captured parts filled with the first plausible
    value it resolves with: the world's mission or log (by the path's app), its drone,
    a fresh id of each kind."""
    if "format" in route:
        return None  # DRF's `.json` twins of the same views
    owned = [ids[app] for app in ids if app in route]
    for filler in (*owned, "ACME_1", str(uuid.uuid4()), "1"):
        path = _filled(route, filler)
        try:
            resolve(path)
        except Resolver404:
            continue
        return None if SKIP.search(path) else path
    return None


def _filled(route: str, filler: str) -> str:
    route = re.sub(r"\(\?P<\w+>[^)]*\)", filler, route)  # regex patterns (DRF, admin)
    route = re.sub(r"<uuid:\w+>", filler if _is_uuid(filler) else str(uuid.uuid4()), route)
    route = re.sub(r"<int:\w+>", "1", route)
    route = re.sub(r"<(?:\w+:)?\w+>", filler, route)
    return "/" + route.replace("^", "").replace("$", "").replace("\\", "").replace("/?", "/")


def _is_uuid(value: str) -> bool:
    try:
        uuid.UUID(value)
    except ValueError:
        return False
    return True


def all_paths(ids: dict[str, str] | None = None) -> list[str]:
    found = {_path(route, ids or {}) for route in _leaves(get_resolver().url_patterns)}
    return sorted(path for path in found if path)


@pytest.mark.django_db
def test_no_page_answers_500_to_malformed_query_parameters(world):
    from logs.models import FlightLog
    from missions.models import Mission

    mission = Mission.objects.create(organisation=world.org, name="walked")
    log = FlightLog.objects.create(
        organisation=world.org, owner=world.operator, name="walked.bin", size=1
    )
    client = Client(raise_request_exception=False)
    client.force_login(world.operator)
    names = parameter_names()
    paths = all_paths({"missions": str(mission.pk), "logs": str(log.pk)})
    assert {f"/missions/{mission.pk}/", f"/api/v1/logs/{log.pk}/series/"} <= set(paths)
    failures = []
    for path in paths:
        for value in MALFORMED:
            response = client.get(path, {name: value for name in names})
            if response.status_code == 500:
                failures.append((path, value, response.status_code))
    assert failures == [], "\n".join(map(repr, failures))


@pytest.mark.django_db
def test_the_log_viewer_answers_404_to_a_mission_that_is_not_an_id(world):
    client = Client()
    client.force_login(world.operator)
    assert client.get("/missions/log-viewer/", {"mission": "x"}).status_code == 404
