"""The landing queue on the real database and Redis: the operator's `return` to a drone
flying a mission stops its part of the mission first (a stop to the drone, an operator
event, the mission stopped when nothing else flies it); a queued drone that does not fly
its hold is sent it again through the outbox, at a bounded rate, its reply read as the
gateway hands it over (airspace/landing.py keep_to_hold)."""

from __future__ import annotations

from datetime import timedelta

import pytest
from django.utils import timezone

from airspace import landing
from airspace.models import LandingSlot
from fleet import commands, envelopes
from fleet.models import Drone
from missions.creation import create_mission
from missions.models import Assignment, Event, MissionStatus
from missions.planning import mission_steps
from missions.progress import apply_progress
from missions.startstop import start_mission
from onboard import protocol
from tests.missions.conftest import online_drone, point_at

pytestmark = pytest.mark.django_db


def in_the_air(drone: Drone, height: float, north: float = 0.0) -> Drone:
    """The drone `height` m up, `north` m from its home at the origin."""
    lat, lon = point_at(north, 0.0)
    Drone.objects.filter(pk=drone.pk).update(
        airborne=True, armed=True, alt=height, lat=lat, lon=lon, home=list(point_at(0.0, 0.0))
    )
    drone.refresh_from_db()
    return drone


def flying_a_mission(org, drone_id: str, height: float, north: float):  # type: ignore[no-untyped-def]
    """The drone started on a survey north of home, now in the air."""
    drone = online_drone(org, drone_id)
    points = [point_at(40.0 * i, 0.0) for i in range(1, 4)]
    mission = create_mission(
        organisation=org, name="north", steps=mission_steps(points, altitude=30)
    )
    assignment = start_mission(mission, drone=drone).assignment
    return in_the_air(drone, height, north), mission, assignment


def sent_to(outbox, drone_id: str, channel: str) -> list[dict]:  # type: ignore[no-untyped-def]
    topic = f"{drone_id}/{channel}/in"
    return [item["payload"] for item in outbox.items() if item["topic"] == topic]


def test_a_return_into_the_queue_stops_the_mission_part_before_the_hold(
    world, outbox, django_capture_on_commit_callbacks
):  # type: ignore[no-untyped-def]
    drone, mission, assignment = flying_a_mission(world.org, "ACME_A", 30.0, north=20.0)
    # A part queued behind it, which the mission would send it once the first one stops.
    queued = Assignment.objects.create(
        mission=mission, drone=drone, step_indexes=[], status=Assignment.Status.QUEUED
    )
    landing.send_home(in_the_air(online_drone(world.org, "ACME_W"), 24.0, north=2.0))
    # Its heartbeat says it flies the mission.
    running = {"mission_id": str(mission.pk), "assignment_id": str(assignment.pk), "index": 3}
    Drone.objects.filter(pk=drone.pk).update(mission=running)
    drone.refresh_from_db()
    outbox.clear()
    with django_capture_on_commit_callbacks(execute=True):
        command, params, queue = landing.route_return(drone)
    # It is sent `hold` (its mission pauses where it is), not yet its hold over home.
    assert (command, params) == ("hold", {})
    assert queue["place"] == 2 and queue["layer_m"] == 44.0
    assert Assignment.objects.get(pk=assignment.pk).status == Assignment.Status.STOPPED
    assert Assignment.objects.get(pk=queued.pk).status == Assignment.Status.STOPPED
    mission.refresh_from_db()
    assert mission.status == MissionStatus.STOPPED
    event = mission.events.get(data__decision="returned")
    assert event.kind == Event.Kind.OPERATOR
    assert event.message == (
        "ACME_A's part stopped: the operator sent it to hold over home at 44 m, "
        "place 2 in the landing queue"
    )
    assert event.data["queue"] == queue
    # One stop, holding where it is.
    stops = sent_to(outbox, "ACME_A", "mission")
    assert [(s["action"], s.get("then")) for s in stops] == [("stop", None)]
    # The hold over home waits while the drone still reports its mission, then goes.
    with django_capture_on_commit_callbacks(execute=True):
        landing.advance()
    assert _holds(outbox, "ACME_A") == []
    Drone.objects.filter(pk=drone.pk).update(mission=None)
    with django_capture_on_commit_callbacks(execute=True):
        landing.advance()
    (hold,) = _holds(outbox, "ACME_A")
    assert hold["params"]["altitude_delta"] == 14.0
    slot = LandingSlot.objects.get(drone=drone, ended_at__isnull=True)
    assert slot.hold_resends == 0 and slot.hold_sent_at is not None


def test_a_return_to_a_free_site_stops_the_part_with_a_return(
    world, outbox, django_capture_on_commit_callbacks
):  # type: ignore[no-untyped-def]
    drone, mission, assignment = flying_a_mission(world.org, "ACME_A", 30.0, north=60.0)
    # Another drone flies the same mission: it goes on with it.
    other = online_drone(world.org, "ACME_B", north=500.0)
    others = Assignment.objects.create(mission=mission, drone=other, step_indexes=[])
    outbox.clear()
    with django_capture_on_commit_callbacks(execute=True):
        assert landing.route_return(drone) is None
    assert Assignment.objects.get(pk=assignment.pk).status == Assignment.Status.STOPPED
    mission.refresh_from_db()
    assert mission.status == MissionStatus.RUNNING
    returned = mission.events.get(data__decision="returned")
    assert "home as before" in returned.message
    stops = sent_to(outbox, "ACME_A", "mission")
    assert [(s["action"], s.get("then")) for s in stops] == [("stop", "return")]
    # Once ACME_B has flown its part, the steps ACME_A left are flown by no drone: the
    # mission is stopped, naming why (it never stays running).
    done = protocol.MissionProgress(str(mission.pk), str(others.pk), "completed")
    assert apply_progress(other, done) is None
    mission.refresh_from_db()
    assert mission.status == MissionStatus.STOPPED
    stopped = mission.events.get(data__decision="stopped")
    assert stopped.data["cause"] == returned.pk and "steps left" in stopped.message


def test_a_return_refused_by_the_envelope_stops_nothing(world, outbox):  # type: ignore[no-untyped-def]
    drone, mission, assignment = flying_a_mission(world.org, "ACME_A", 30.0, north=20.0)
    landing.send_home(in_the_air(online_drone(world.org, "ACME_W"), 24.0, north=2.0))
    # Its own ceiling is 25 m: no layer under it is clear, so it would hold at its 30 m,
    # which the envelope refuses.
    Drone.objects.filter(pk=drone.pk).update(max_height=25.0)
    drone.refresh_from_db()
    with pytest.raises(envelopes.EnvelopeRefusal):
        landing.route_return(drone)
    assert Assignment.objects.get(pk=assignment.pk).status == Assignment.Status.SENT
    assert not LandingSlot.objects.filter(drone=drone).exists()
    assert not mission.events.filter(data__decision="returned").exists()


def _age_the_watch(drone: Drone, seconds: float = 11.0) -> None:
    LandingSlot.objects.filter(drone=drone, ended_at__isnull=True).update(
        watched_at=timezone.now() - timedelta(seconds=seconds)
    )


def _holds(outbox, drone_id: str) -> list[dict]:  # type: ignore[no-untyped-def]
    return [m for m in sent_to(outbox, drone_id, "control") if m["command"] == "navigate"]


def test_a_hold_not_flown_is_sent_again_once_per_window_and_its_reply_read(
    world, outbox, django_capture_on_commit_callbacks
):  # type: ignore[no-untyped-def]
    def advance() -> list[str]:
        with django_capture_on_commit_callbacks(execute=True):
            return landing.advance()

    landing.send_home(in_the_air(online_drone(world.org, "ACME_W"), 24.0, north=2.0))
    drone = in_the_air(online_drone(world.org, "ACME_T"), 30.0, north=20.0)
    assert landing.send_home(drone).layer_m == 44.0
    outbox.clear()
    # Within its first window: nothing again.
    advance()
    assert _holds(outbox, "ACME_T") == []
    # A window with no move towards the hold (the navigate was lost): sent again, from
    # where the drone is (its reported height), to home at its layer.
    _age_the_watch(drone)
    advance()
    (hold,) = _holds(outbox, "ACME_T")
    home = point_at(0.0, 0.0)
    assert hold["params"] == {"lat": home[0], "lon": home[1], "altitude_delta": 14.0}
    slot = LandingSlot.objects.get(drone=drone, ended_at__isnull=True)
    assert slot.hold_resends == 1 and slot.hold_request == hold["request_id"]
    # Not again in the same window, whatever the drone does meanwhile.
    advance()
    assert len(_holds(outbox, "ACME_T")) == 1
    # The drone's answer, handed over by the gateway as every reply is, is read.
    target = {"north": 0.0, "east": 0.0, "down": -44.0}
    reply = protocol.ControlResponse(hold["request_id"], "navigate", True, {"target": target})
    assert commands.handle_control_reply("ACME_T", reply) is None
    advance()
    slot.refresh_from_db()
    assert slot.hold_accepted_at is not None and slot.hold_request == ""
    # On its way (nearer by more than the tolerance): watched again, not sent again.
    in_the_air(drone, 37.0, north=8.0)
    _age_the_watch(drone)
    advance()
    assert len(_holds(outbox, "ACME_T")) == 1
    # Hovering at its hold, a few metres off (position noise): left alone.
    in_the_air(drone, 45.5, north=4.0)
    _age_the_watch(drone)
    advance()
    assert len(_holds(outbox, "ACME_T")) == 1
    # Stalled short of it once its re-sends are spent: it leaves the queue.
    in_the_air(drone, 37.0, north=8.0)
    LandingSlot.objects.filter(pk=slot.pk).update(hold_resends=5)
    _age_the_watch(drone)
    advance()
    slot.refresh_from_db()
    assert slot.end_reason == "its hold was not flown after 5 re-sends"
    assert len(_holds(outbox, "ACME_T")) == 1


def test_a_hold_refused_by_the_drone_or_answered_by_none_is_handled(
    world, outbox, django_capture_on_commit_callbacks
):  # type: ignore[no-untyped-def]
    landing.send_home(in_the_air(online_drone(world.org, "ACME_W"), 24.0, north=2.0))
    drone = in_the_air(online_drone(world.org, "ACME_T"), 30.0, north=20.0)
    assert landing.route_return(drone) is not None
    # The operator's hold went unanswered: the drone keeps its place, for the re-send.
    landing.return_answered(drone, "return", None)
    slot = LandingSlot.objects.get(drone=drone)
    assert slot.ended_at is None
    _age_the_watch(drone)
    with django_capture_on_commit_callbacks(execute=True):
        landing.advance()
    (hold,) = _holds(outbox, "ACME_T")
    refusal = protocol.ControlResponse(hold["request_id"], "navigate", False, None, "No GPS fix.")
    assert commands.handle_control_reply("ACME_T", refusal) is None
    with django_capture_on_commit_callbacks(execute=True):
        landing.advance()
    slot.refresh_from_db()
    assert slot.end_reason == "its hold was refused: No GPS fix."
