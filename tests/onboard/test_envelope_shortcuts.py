"""Legs sent before the last one ends (onboard/envelope.py `fan_origins`), without a drone.

Rule: a move sent while earlier moves are still under way (no wait_for_flight since them;
a sleep does not end them) may be flown from anywhere along them, so it is checked as a
fan of legs from points at most 10 m apart along them to its target; the planned leg
from the previous target and the shortcut from where they began are both in it. On the
drone, a command arriving while it is still on its way to its last target is checked
from where it is as well as from that target.
"""

from __future__ import annotations

import math

import pytest

from onboard import envelope as env
from onboard.controller import CommandError, Controller
from onboard.navigation import NavigationProcessor

from .fakes import HOME as FC_HOME
from .fakes import FakeFlightController

HOME = (40.6300, -8.6600)
WAIT = {
    "command": "wait_for_flight",
    "params": {"horizontal_tolerance": 2, "vertical_tolerance": 2},
}
# An L-shaped (concave) inclusion fence: a strip 40 m wide up the north axis to 120 m,
# and one 40 m wide east along 80–120 m north. Home → (100, 0) → (100, 80) stays in it;
# home → (100, 80) straight cuts the inside corner and leaves it.
L_FENCE = [(-20, -20), (120, -20), (120, 100), (80, 100), (80, 20), (-20, 20)]


def _polygon(corners, inclusion: bool, home=HOME) -> dict:  # type: ignore[no-untyped-def]
    points = [list(env.ned_to_latlon(n, e, home)) for n, e in corners]
    return {"inclusion": inclusion, "polygon": points, "version": 1}


def _circle(north: float, east: float, radius: float, home=HOME) -> dict:  # type: ignore[no-untyped-def]
    center = list(env.ned_to_latlon(north, east, home))
    return {"inclusion": False, "circle": {"center": center, "radius": radius}, "version": 1}


def _envelope(polygons=(), circles=(), home=HOME) -> env.Envelope:  # type: ignore[no-untyped-def]
    fence = {"version": 2, "polygons": list(polygons), "circles": list(circles)}
    return env.parse_envelope({"geoFence": fence}, home=home)


def _navigate(north: float, east: float) -> dict:
    lat, lon = env.ned_to_latlon(north, east, HOME)
    return {"command": "navigate", "params": {"lat": lat, "lon": lon}}


def _mission(*between: dict) -> list[dict]:
    return [
        {"command": "takeoff", "params": {"altitude": 10}},
        WAIT,
        _navigate(100, 0),
        *between,
        _navigate(100, 80),
        {"command": "land"},
    ]


def _refused(envelope: env.Envelope, steps: list[dict]) -> list[tuple[int, str]]:
    found = env.step_violations(envelope, HOME, steps, (0.0, 0.0, 0.0), False, None)
    return [(v.index, v.violation.message) for v in found]


def test_the_fan_spans_the_unfinished_leg_at_most_the_spacing_apart() -> None:
    origins = env.fan_origins([(0.0, 0.0, -10.0), (0.0, 35.0, -10.0)])
    # The start of the unfinished leg is in it; its end (the planned start) is the
    # planned leg's, so it is left out here.
    assert origins[0] == (0.0, 0.0, -10.0)
    easts = sorted(p[1] for p in origins)
    gaps = [b - a for a, b in zip([*easts, 35.0], [*easts, 35.0][1:], strict=False)]
    assert max(gaps) <= env.FAN_SPACING_M and easts[-1] < 35.0
    assert env.fan_origins([(5.0, 5.0, -10.0)]) == []  # nothing under way


def test_the_fan_is_capped_and_coarser_past_the_cap() -> None:
    origins = env.fan_origins([(0.0, 0.0, -10.0), (1000.0, 0.0, -10.0)])
    assert len(origins) < env.FAN_MAX_ORIGINS
    norths = sorted(p[0] for p in origins)
    assert norths[0] == 0.0 and 1000.0 - norths[-1] <= 1000.0 / (env.FAN_MAX_ORIGINS - 1) + 1e-6


def test_after_several_unfinished_legs_the_fan_runs_round_their_hull() -> None:
    # Home → (0, 100) → (100, 100) unfinished: the drone may be anywhere in that triangle,
    # so its diagonal (home → (100, 100), itself a possible leg) is in the fan too.
    origins = env.fan_origins([(0.0, 0.0, -10.0), (0.0, 100.0, -10.0), (100.0, 100.0, -10.0)])
    on_diagonal = [p for p in origins if abs(p[0] - p[1]) < 1e-6 and 0 < p[0] < 100]
    assert on_diagonal and all(math.isfinite(p[2]) for p in origins)


@pytest.mark.parametrize(
    ("fence", "words"),
    [
        ({"polygons": [_polygon(L_FENCE, inclusion=True)]}, "leaves the geofence's inclusion"),
        # An exclusion circle inside the corner the shortcut cuts.
        ({"circles": [_circle(40, 30, 10)]}, "exclusion circle 0"),
    ],
)
def test_cutting_the_corner_of_an_unfinished_leg_is_refused_and_waiting_allows_it(
    fence: dict, words: str
) -> None:
    envelope = _envelope(**fence)
    ((index, message),) = _refused(envelope, _mission())
    assert index == 3 and words in message and "wait_for_flight" in message
    # A sleep waits a time, not an arrival: the corner may still be cut.
    slept = _refused(envelope, _mission({"command": "sleep", "params": {"value": 3}}))
    assert [i for i, _ in slept] == [4]
    assert _refused(envelope, _mission(WAIT)) == []


def test_the_walk_yields_the_fan_after_the_planned_leg_with_the_same_step() -> None:
    legs = [leg for leg in env.walk(HOME, _mission(), (0.0, 0.0, 0.0), False) if leg[0] == 3]
    (index, move, planned_start, _), *fan = legs
    assert planned_start == pytest.approx((100.0, 0.0, -10.0))
    assert fan and all(leg[1] == move for leg in fan)
    assert any(leg[2][:2] == pytest.approx((0.0, 0.0)) for leg in fan)  # the shortcut
    # The path as drawn is the planned legs only.
    drawn = [leg for leg in env.walk(HOME, _mission(), (0.0, 0.0, 0.0), False, shortcuts=False)]
    assert [leg[0] for leg in drawn] == [0, 2, 3, 4]


def test_a_command_is_checked_from_where_the_drone_is_while_it_is_on_its_way() -> None:
    assert env.command_starts((100.0, 0.0, -10.0), (1.0, 0.0, -10.0)) == [
        (100.0, 0.0, -10.0),
        (1.0, 0.0, -10.0),
    ]
    assert env.command_starts((100.0, 0.0, -10.0), (99.0, 0.5, -10.0)) == [(100.0, 0.0, -10.0)]
    assert env.command_starts(None, (1.0, 0.0, -10.0)) == [(1.0, 0.0, -10.0)]


def test_the_agent_refuses_a_command_whose_leg_from_where_the_drone_is_crosses(tmp_path) -> None:  # type: ignore[no-untyped-def]
    home = FC_HOME[:2]
    guard = env.EnvelopeGuard(tmp_path / "envelope.json")
    guard.update({"geoFence": {"circles": [_circle(40, 30, 10, home=home)]}})
    fc = FakeFlightController()
    fc.arm()
    fc.move_to(0.0, 0.0, -10.0)
    controller = Controller(fc, NavigationProcessor(fc), guard=guard.refusal)

    def navigate(north: float, east: float) -> dict:
        lat, lon = env.ned_to_latlon(north, east, home)
        return controller.execute("navigate", {"lat": lat, "lon": lon})

    navigate(100, 0)  # the drone has not left: it is still on its way to this target
    with pytest.raises(CommandError) as refused:
        navigate(100, 80)
    assert "exclusion circle 0" in str(refused.value) and "where the drone is now" in str(
        refused.value
    )
    assert fc.calls[-1][:2] == ("goto", pytest.approx(100.0, abs=0.01))  # nothing new sent
    fc.move_to(100.0, 0.0, -10.0)  # arrived: the leg from there is clear
    assert navigate(100, 80)["target"]["east"] == pytest.approx(80.0, abs=0.01)
