"""The agent's last-resort separation check: relayed traffic parsed (a malformed message
counted by its reason), kept while fresh, flown on against the drone's own state; and the
fail-safe's return kept inside the reservation's band."""

from __future__ import annotations

import pytest

from onboard import protocol
from onboard.failsafe import FailSafe, Limits
from onboard.fc.base import VehicleState
from onboard.navigation import ned_to_lla
from onboard.traffic import (
    Other,
    TrafficError,
    TrafficWatch,
    first_loss,
    parse_traffic,
    traffic_message,
)

from .fakes import HOME, FakeFlightController


class Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def other_at(north: float, east: float = 0.0, alt: float = 20.0, vn: float = 0.0) -> Other:
    lat, lon, _ = ned_to_lla(north, east, -alt, HOME)
    return Other("ACME_B", lat, lon, alt, 0.0, vn, 0.0, 30.0, 10.0)


def flying(north: float = 0.0, vn: float = 0.0, alt: float = 20.0) -> VehicleState:
    lat, lon, _ = ned_to_lla(north, 0.0, -alt, HOME)
    return VehicleState(
        armed=True, lat=lat, lon=lon, alt=alt, ned=(north, 0.0, -alt), velocity_ned=(vn, 0, 0)
    )


def test_the_ground_message_round_trips_and_is_an_optional_qos0_input_channel():
    message = traffic_message(1e9, (30.0, 40.0), [other_at(50)])
    update = parse_traffic(message)
    assert update.band == (30.0, 40.0) and update.others == (other_at(50),)
    assert protocol.topic("ACME_A", "traffic", "in") == "ACME_A/traffic/in"
    assert protocol.QOS["traffic"] == 0
    assert protocol.PARSERS[("traffic", "in")](message) == update


@pytest.mark.parametrize(
    ("change", "reason"),
    [
        (lambda m: [], "shape"),
        (lambda m: {**m, "traffic": "ACME_B"}, "shape"),
        (lambda m: {**m, "ts": "yesterday"}, "ts"),
        (lambda m: {**m, "band": [40, 30]}, "band"),
        (lambda m: {**m, "band": [30]}, "band"),
        (lambda m: {**m, "traffic": [{**m["traffic"][0], "lat": 91}]}, "position"),
        (lambda m: {**m, "traffic": [{**m["traffic"][0], "alt": float("nan")}]}, "position"),
        (lambda m: {**m, "traffic": [{**m["traffic"][0], "vn": True}]}, "velocity"),
        (lambda m: {**m, "traffic": [{**m["traffic"][0], "ve": 1e4}]}, "velocity"),
        (lambda m: {**m, "traffic": [{**m["traffic"][0], "vertical_min_m": -1}]}, "minima"),
        (lambda m: {**m, "traffic": [{**m["traffic"][0], "drone_id": "../x"}]}, "drone_id"),
        (lambda m: {**m, "traffic": [m["traffic"][0]] * 33}, "too_many"),
    ],
)
def test_a_malformed_message_is_refused_with_its_reason(change, reason):
    message = traffic_message(1e9, (30.0, 40.0), [other_at(50)])
    with pytest.raises(TrafficError) as refused:
        parse_traffic(change(message))
    assert refused.value.reason == reason


def test_head_on_predicted_within_the_shorter_horizon_only():
    # 100 m apart closing at 10 m/s: under 30 m after 7 s, beyond a 6 s horizon.
    assert first_loss((0, 0, 20, 0, 5, 0), (0, 100, 20, 0, -5, 0), (30, 10), 6.0) is None
    in_s, horizontal, _ = first_loss((0, 0, 20, 0, 5, 0), (0, 80, 20, 0, -5, 0), (30, 10), 6.0)
    assert in_s == pytest.approx(5.25) and horizontal < 30
    # 12 m apart vertically: separated however close horizontally.
    assert first_loss((0, 0, 20, 0, 5, 0), (0, 80, 32, 0, -5, 0), (30, 10), 6.0) is None


def test_an_encounter_is_reported_once_until_clear_and_stale_traffic_is_forgotten():
    clock, state = Clock(), [flying(0, vn=5)]
    watch = TrafficWatch("ACME_A", lambda: state[0], clock=clock)
    update = parse_traffic(traffic_message(1e9, None, [other_at(70, vn=-5)]))
    assert watch.receive(update, age_s=0.5)
    (met,) = watch.check()
    # Relayed 0.5 s ago: flown on to 67.5 m now; closing at 10 m/s → under 30 m at 3.75 s.
    assert met.other == "ACME_B" and met.in_s == pytest.approx(3.75)
    assert watch.check() == []  # the same encounter: no second report
    clock.now += 3.0  # 3.5 s after its time stamp: stale, forgotten
    assert watch.current() == [] and watch.check() == []
    assert not watch.receive(update, age_s=4.0)  # arrived stale: not kept
    assert watch.current() == []


def test_own_entry_is_ignored_and_nothing_is_checked_on_the_ground():
    state = [flying(0)]
    watch = TrafficWatch("ACME_B", lambda: state[0], clock=Clock())
    watch.receive(parse_traffic(traffic_message(1e9, None, [other_at(5)])), 0.0)
    assert watch.current() == []
    watch = TrafficWatch("ACME_A", lambda: state[0], clock=Clock())
    watch.receive(parse_traffic(traffic_message(1e9, None, [other_at(5)])), 0.0)
    state[0] = VehicleState(armed=False, lat=state[0].lat, lon=state[0].lon, alt=0.0)
    assert watch.check() == []


def test_time_scale_shortens_the_horizon_in_ground_seconds():
    clock, state = Clock(), [flying(0, vn=5)]
    update = parse_traffic(traffic_message(1e9, None, [other_at(92, vn=-10)]))
    # Own 5 m/s per flight second is 10 m/s on a clock twice as slow; the other closes at
    # 10: 92 m → 30 m takes 3.1 s, just beyond the 6 flight-second horizon over 2.
    watch = TrafficWatch("ACME_A", lambda: state[0], clock=clock, time_scale=2.0)
    watch.receive(update, 0.0)
    assert watch.check() == []
    watch = TrafficWatch("ACME_A", lambda: state[0], clock=clock, time_scale=2.0, horizon_s=6.5)
    watch.receive(update, 0.0)
    assert [m.other for m in watch.check()] == ["ACME_B"]


def _failsafe(fc: FakeFlightController) -> FailSafe:
    return FailSafe(fc, lambda *a, **k: None, limits=Limits(), clock=Clock())


def test_a_return_above_its_band_descends_into_it_first_then_flies_home_inside_it():
    fc = FakeFlightController()
    fc.arm()
    fc.move_to(60, 0, -50)
    failsafe = _failsafe(fc)
    failsafe.band = (20.0, 40.0)
    assert failsafe.return_home("ground link lost") == "return"
    assert fc.calls[-1] == ("goto", 60, 0, -40.0)  # straight down into the band
    failsafe.check_recovery()
    assert fc.calls[-1] == ("goto", 60, 0, -40.0)  # not there yet
    fc.move_to(60, 0, -40.4)
    failsafe.check_recovery()
    assert fc.calls[-1] == ("goto", 0.0, 0.0, -40.0)  # then home inside it
    fc.move_to(0.5, 0, -40)
    failsafe.check_recovery()
    assert fc.calls[-1] == ("land",)


def test_a_return_inside_its_band_or_without_one_flies_home_at_its_height():
    for band in ((20.0, 40.0), None):
        fc = FakeFlightController()
        fc.arm()
        fc.move_to(60, 0, -30)
        failsafe = _failsafe(fc)
        failsafe.band = band
        failsafe.return_home("ground link lost")
        assert fc.calls[-1] == ("goto", 0.0, 0.0, -30)


def test_the_band_is_forgotten_once_disarmed():
    fc = FakeFlightController()
    failsafe = _failsafe(fc)
    failsafe.band = (20.0, 40.0)
    failsafe.tick()
    assert failsafe.band is None
