"""Published zones speed: a command's zone check with a national ED-269 file imported,
and the import itself.

Run: .venv/bin/python -m bench.bench_zones

A generated ED-269 file of ZONES zones (circles and polygons of 8 to 32 vertices, a
quarter of them with several volumes) scattered over a 300 km square is imported
site-wide into a database of its own. The first figure is `move_violation` (what
fleet/envelopes.py calls for every command) for a 1 km `navigate` leg through the
densest part, at 40 m; its baseline, measured in the same run, is the envelope's own check
of the same move (`onboard.envelope.check`, every command's existing cost). The second is
the import of the whole file (read, checked, stored in one transaction); its baseline is
`json.loads` of the same bytes. The third is the shape check of one polygon of 1 000
vertices (the most a zone's polygon may have), whose self-intersection test sweeps the
edges; its baseline is the plain test of every pair of edges.
"""

from __future__ import annotations

import json
import math
import os
import random

os.environ.setdefault("DJANGO_SETTINGS_MODULE", "config.settings.test")
os.environ["TEST_DB_NAME"] = f"bench_zones_{os.getpid()}"

ZONES = 5000
HOME = (40.6303, -8.6575)
SPREAD_M = 150_000.0
CHECK_GOAL = "a command's zone check in at most 5 ms with a 5 000-zone national file"
IMPORT_GOAL = "a 5 000-zone ED-269 file imported in at most 30 s"


def _volume(rng: random.Random, north: float, east: float) -> dict:
    from onboard.envelope import ned_to_latlon

    limits = {
        "uomDimensions": "M",
        "lowerLimit": 0,
        "lowerVerticalReference": "AGL",
        "upperLimit": rng.choice([60, 120, 150]),
        "upperVerticalReference": "AGL",
    }
    radius = rng.uniform(100.0, 3000.0)
    if rng.random() < 0.4:
        lat, lon = ned_to_latlon(north, east, HOME)
        projection = {"type": "Circle", "center": [lon, lat], "radius": radius}
    else:
        count = rng.randint(8, 32)
        ring = []
        for k in range(count):
            angle = 2 * math.pi * k / count
            r = radius * rng.uniform(0.7, 1.0)
            lat, lon = ned_to_latlon(north + r * math.cos(angle), east + r * math.sin(angle), HOME)
            ring.append([lon, lat])
        projection = {"type": "Polygon", "coordinates": [[*ring, ring[0]]]}
    return {**limits, "horizontalProjection": projection}


def national_file(seed: int = 7) -> bytes:
    """ZONES zones, denser near home (half of them within 20 km)."""
    rng = random.Random(seed)
    features = []
    for i in range(ZONES):
        spread = 20_000.0 if i % 2 else SPREAD_M
        north, east = rng.uniform(-spread, spread), rng.uniform(-spread, spread)
        volumes = [_volume(rng, north, east) for _ in range(3 if i % 4 == 0 else 1)]
        features.append(
            {
                "identifier": f"BENCH-{i:05d}",
                "country": "PRT",
                "name": f"Zone {i}",
                "type": "COMMON",
                "restriction": rng.choice(["PROHIBITED", "REQ_AUTHORISATION", "CONDITIONAL"]),
                "applicability": [{"permanent": "YES"}],
                "zoneAuthority": [],
                "geometry": volumes,
            }
        )
    document = {"title": "bench", "description": "generated", "features": features}
    return json.dumps(document).encode()


def survey_steps() -> list[dict]:
    """Take off to 100 m, then 1 000 waypoints 10 m apart in rows of 20 (a lawnmower)."""
    from onboard.envelope import ned_to_latlon

    steps = [{"command": "takeoff", "params": {"altitude": 100}}]
    for k in range(1000):
        row, column = divmod(k, 20)
        east = column if row % 2 == 0 else 19 - column
        lat, lon = ned_to_latlon(row * 10.0, east * 10.0, HOME)
        steps.append({"command": "navigate", "params": {"lat": lat, "lon": lon}})
    return steps


def every_pair(ring: list[tuple[float, float]]) -> bool:
    """The baseline: every pair of non-adjacent edges tested."""
    from onboard.envelope import _segments_cross

    edges = [(ring[i], ring[(i + 1) % len(ring)]) for i in range(len(ring))]
    for i in range(len(edges)):
        for j in range(i + 2, len(edges)):
            if not (i == 0 and j == len(edges) - 1) and _segments_cross(*edges[i], *edges[j]):
                return True
    return False


def polygon_check() -> None:
    from bench.common import best_of, record
    from onboard import envelope as env

    ring = [
        (40 + 0.01 * math.cos(2 * math.pi * k / 1000), -8 + 0.01 * math.sin(2 * math.pi * k / 1000))
        for k in range(1000)
    ]
    local = [env.latlon_to_ne(lat, lon, ring[0]) for lat, lon in ring]
    assert env._self_intersects(local) is every_pair(local) is False
    fence = {"polygons": [{"inclusion": False, "polygon": [list(p) for p in ring]}]}
    value = best_of(lambda: env.parse_geofence(fence), repeat=5)
    baseline = best_of(lambda: every_pair(local), repeat=1)
    record(
        "zones.polygon_1000_vertices_check_s",
        value=value,
        unit="s",
        baseline_name="every pair of edges tested for crossing",
        baseline_value=baseline,
        higher_is_better=False,
        goal="a 1 000-vertex zone polygon checked in at most 0.2 s",
    )


def command_check(organisation, stored: int) -> None:  # type: ignore[no-untyped-def]
    from bench.common import best_of, record
    from onboard import envelope as env
    from zones.enforcement import move_violation

    north, east = env.latlon_to_ne(*env.ned_to_latlon(600.0, 800.0, HOME), HOME)
    move = env.Move("goto", (north, east, -40.0), True)
    start = (0.0, 0.0, -40.0)
    found = move_violation(organisation, HOME, move, start, True)
    check = best_of(lambda: move_violation(organisation, HOME, move, start, True), repeat=50)
    envelope = env.Envelope()
    baseline = best_of(lambda: env.check(envelope, HOME, move, True, 90.0, start), repeat=50)
    record(
        "zones.command_check_s",
        value=check,
        unit="s",
        baseline_name="the envelope's own check of the same move (onboard.envelope.check)",
        baseline_value=baseline,
        higher_is_better=False,
        goal=CHECK_GOAL,
        zones_stored=stored,
        refused=found is not None,
        measured="a 1 km navigate leg at 40 m from home, database warm; best of 50",
    )


def mission_check(organisation, stored: int) -> None:  # type: ignore[no-untyped-def]
    from bench.common import best_of, record
    from onboard import envelope as env
    from zones.enforcement import step_violations

    survey = survey_steps()
    walked = best_of(
        lambda: step_violations(organisation, HOME, survey, (0.0, 0.0, 0.0), False), repeat=3
    )
    wide = env.Envelope(max_distance=5000.0)
    plain = best_of(
        lambda: env.step_violations(wide, HOME, survey, (0.0, 0.0, 0.0), False, None), repeat=3
    )
    record(
        "zones.mission_1000_steps_s",
        value=walked,
        unit="s",
        baseline_name="the envelope's own walk of the same steps (onboard.envelope)",
        baseline_value=plain,
        higher_is_better=False,
        goal="a 1 000-waypoint mission's zone check in at most 0.5 s",
        zones_stored=stored,
        measured="a 200 x 500 m survey at 100 m near home, every leg within the band "
        "of the zones around it; best of 3",
    )


def import_check(data: bytes) -> int:
    """Import the file (timed once) and record it; the zones stored."""
    from bench.common import best_of, record
    from zones.models import Zone
    from zones.store import import_bytes

    imported = best_of(lambda: import_bytes("national.json", data), repeat=1)
    parsed = best_of(lambda: json.loads(data), repeat=3)
    stored = Zone.objects.count()
    record(
        "zones.import_national_file_s",
        value=imported,
        unit="s",
        baseline_name="json.loads of the same file",
        baseline_value=parsed,
        higher_is_better=False,
        goal=IMPORT_GOAL,
        file_bytes=len(data),
        zones_stored=stored,
    )
    return stored


def main() -> None:
    import django

    django.setup()
    from django.db import connection

    from fleet.models import Organisation

    original_database = connection.settings_dict["NAME"]
    connection.creation.create_test_db(verbosity=0, autoclobber=True, serialize=False)
    try:
        organisation = Organisation.objects.create(slug="bench", name="Bench")
        stored = import_check(national_file())
        command_check(organisation, stored)
        mission_check(organisation, stored)
    finally:
        if connection.settings_dict["NAME"] != original_database:
            connection.creation.destroy_test_db(original_database, verbosity=0)


if __name__ == "__main__":
    polygon_check()
    main()
