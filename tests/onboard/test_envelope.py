"""The flight envelope's rules and geometry (onboard/envelope.py), without a drone."""

from __future__ import annotations

import pytest

from onboard import envelope as env

HOME = (40.6300, -8.6600)


def _square(half_m: float, center: tuple[float, float] = HOME) -> list[list[float]]:
    """A square of side 2·half_m metres about `center`, as [lat, lon] vertices."""
    corners = [(-half_m, -half_m), (-half_m, half_m), (half_m, half_m), (half_m, -half_m)]
    return [list(env.ned_to_latlon(n, e, center)) for n, e in corners]


def _fence(polygons=(), circles=()) -> dict:  # type: ignore[no-untyped-def]
    return {"version": 2, "polygons": list(polygons), "circles": list(circles)}


def _goto(north: float, east: float, height: float, horizontal: bool = True) -> env.Move:
    return env.Move("goto", (north, east, -height), horizontal)


def test_defaults_allow_a_hundred_metres_north_at_ten_metres() -> None:
    envelope = env.parse_envelope({})
    assert (envelope.max_height, envelope.max_distance) == (120.0, 1000.0)
    assert env.check(envelope, HOME, _goto(100, 0, 10), True, 90.0) is None


@pytest.mark.parametrize(
    ("move", "battery", "limit"),
    [
        (_goto(0, 0, 150, horizontal=False), 90.0, "max_height"),
        (_goto(900, 900, 10), 90.0, "max_distance"),
        (_goto(50, 0, 1), 90.0, "min_move_height"),
        (_goto(50, 0, 10), 20.0, "battery_reserve"),
        (env.Move("takeoff", (0, 0, -10)), 20.0, "battery_reserve"),
    ],
)
def test_each_limit_is_named(move: env.Move, battery: float, limit: str) -> None:
    violation = env.check(env.parse_envelope({}), HOME, move, True, battery)
    assert violation is not None and violation.limit == limit
    assert violation.message.endswith(".")


def test_under_the_reserve_land_and_return_home_pass() -> None:
    envelope = env.parse_envelope({})
    assert env.check(envelope, HOME, env.Move("land", (80, 0, 0)), True, 10.0) is None
    assert env.check(envelope, HOME, _goto(1, 1, 10), True, 10.0) is None


def test_inclusion_polygon_and_exclusion_circle() -> None:
    exclusion_center = env.ned_to_latlon(50, 0, HOME)
    envelope = env.parse_envelope(
        {
            "geoFence": _fence(
                polygons=[{"inclusion": True, "polygon": _square(100), "version": 1}],
                circles=[
                    {
                        "inclusion": False,
                        "circle": {"center": list(exclusion_center), "radius": 20},
                        "version": 1,
                    }
                ],
            )
        },
        home=HOME,
    )
    assert env.check(envelope, HOME, _goto(0, 80, 10), True, None) is None
    outside = env.check(envelope, HOME, _goto(0, 150, 10), True, None)
    assert outside is not None and "inclusion" in outside.message
    excluded = env.check(envelope, HOME, _goto(55, 0, 10), True, None)
    assert excluded is not None and "exclusion circle 0" in excluded.message


def test_the_fence_round_trips_in_qgc_shape() -> None:
    fence = _fence(polygons=[{"inclusion": False, "polygon": _square(30), "version": 1}])
    envelope = env.parse_envelope({"geoFence": fence})
    assert envelope.to_dict()["geoFence"] == fence


@pytest.mark.parametrize(
    ("body", "field"),
    [
        ({"max_height": -5}, "max_height"),
        ({"max_distance": "far"}, "max_distance"),
        ({"geoFence": _fence(polygons=[{"polygon": [[40.6, -8.6], [40.7, -8.6]]}])}, "polygon"),
        (
            {
                "geoFence": _fence(
                    polygons=[
                        {
                            "polygon": [
                                [40.62, -8.67],
                                [40.64, -8.65],
                                [40.64, -8.67],
                                [40.62, -8.65],
                            ]
                        }
                    ]
                )
            },
            "geoFence.polygons[0].polygon",
        ),
        ({"geoFence": _fence(polygons=[{"polygon": _square(50, (40.70, -8.66))}])}, "geoFence"),
        ({"geoFence": _fence(circles=[{"circle": {"center": list(HOME), "radius": 0}}])}, "radius"),
    ],
)
def test_malformed_envelopes_name_the_field(body: dict, field: str) -> None:
    with pytest.raises(env.EnvelopeError) as caught:
        env.parse_envelope(body, home=HOME)
    assert field in caught.value.field


def test_a_drone_may_only_lower_the_limits() -> None:
    envelope = env.parse_envelope({}).restricted(max_height=500, max_distance=200)
    assert (envelope.max_height, envelope.max_distance) == (120.0, 200.0)


def test_steps_resolve_relative_moves_from_the_current_target() -> None:
    steps = [
        {"command": "takeoff", "params": {"altitude": 10}},
        {"command": "changeN", "params": {"value": 600}},
        {"command": "takepic", "params": {}},
        {"command": "changeN", "params": {"value": 600}},
    ]
    found = env.check_steps(env.parse_envelope({}), HOME, steps, (0, 0, 0), False, 90.0)
    assert found is not None and found.index == 3 and found.violation.limit == "max_distance"
    assert env.check_steps(env.parse_envelope({}), HOME, steps[:3], (0, 0, 0), False, 90.0) is None


class _State:
    home = (*HOME, 12.0)
    airborne = True
    battery_remaining = 0.9


def test_the_guard_keeps_the_last_envelope_across_restarts(tmp_path) -> None:  # type: ignore[no-untyped-def]
    path = tmp_path / "envelope.json"
    assert env.EnvelopeGuard(path).envelope == env.Envelope()
    env.EnvelopeGuard(path).update({"max_height": 40})
    restarted = env.EnvelopeGuard(path)
    assert restarted.envelope.max_height == 40
    refusal = restarted.refusal("altitude", "goto", (0.0, 0.0, -50.0), _State())
    assert refusal is not None and "maximum height of 40 m" in refusal
    assert restarted.refusal("land", "land", (0.0, 0.0, 0.0), _State()) is None
    drained = _State()
    drained.battery_remaining = 0.2
    low = restarted.refusal("changeN", "goto", (50.0, 0.0, -10.0), drained)
    assert low is not None and "reserve" in low
    # A mission already flying is left to the fail-safe's battery alarm.
    assert restarted.refusal("changeN", "goto", (50.0, 0.0, -10.0), drained, True) is None
    path.write_text("{not json")
    assert env.EnvelopeGuard(path).envelope == env.Envelope()  # the defaults, never none
