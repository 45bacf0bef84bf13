"""The ground's side of the flight envelope: storing it, sending it, checking moves against it.

The rules themselves live once in onboard/envelope.py, which the drones run too. Here a
drone's moves are resolved from its *current target* (the last target it accepted from
the ground, else its reported position) about its *home* (where the ground last saw it at
rest), and refused before anything is sent.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import replace
from typing import Any

from django.conf import settings
from django.db import transaction
from django.utils.module_loading import import_string

from onboard import envelope as env
from onboard import protocol
from terrain import guard as terrain
from terrain.climbout import Climb, Paced, climb_slope
from workers import outbox

from .identity import identity_for
from .models import Drone, Organisation
from .signals import envelope_changed

log = logging.getLogger(__name__)

OUTSIDE_ENVELOPE = "outside_envelope"
CONFIRMATION_REQUIRED = "confirmation_required"
# An envelope message lives in the outbox for a day: a drone that was away gets it on
# its next heartbeat anyway (send_to_drones on drones_came_online).
ENVELOPE_TTL_S = 86_400.0


class EnvelopeRefusal(Exception):
    """A move refused before sending; `message` names the limit (and the step of a
    mission), `code` is the API's error code."""

    code = OUTSIDE_ENVELOPE

    def __init__(self, violation: env.Violation, step: int | None = None) -> None:
        prefix = "" if step is None else f"Step {step}: "
        self.message = prefix + violation.message
        # A published zone's violation carries its own code (`zone`).
        self.code = getattr(violation, "code", self.code)
        self.limit = violation.limit
        self.step = step
        super().__init__(self.message)


class OutsideEnvelope(EnvelopeRefusal):
    """A move the envelope refuses."""


class NeedsConfirmation(EnvelopeRefusal):
    """A move inside the envelope but beyond its defaults, sent without a confirmation."""

    code = CONFIRMATION_REQUIRED


# -- storing ------------------------------------------------------------------------------


def organisation_envelope(organisation: Organisation) -> env.Envelope:
    """The organisation's envelope (the defaults when none was set)."""
    return env.parse_envelope(organisation.envelope or {})


def envelope_body(organisation: Organisation) -> dict:
    """What the API shows: the limits, the QGroundControl geoFence and the reference home."""
    return {
        **organisation_envelope(organisation).to_dict(),
        "home": (organisation.envelope or {}).get("home"),
    }


def plan_document(organisation: Organisation) -> dict:
    """The geofence as a QGroundControl `.plan` file with no mission items."""
    home = (organisation.envelope or {}).get("home")
    fence = env.geofence_dict(organisation_envelope(organisation))
    # QGroundControl refuses a plan without a home: the fence's first point stands in.
    anchors = [p["polygon"][0] for p in fence["polygons"]]
    anchors += [c["circle"]["center"] for c in fence["circles"]]
    home = home or (anchors[0] if anchors else None)
    return {
        "fileType": "Plan",
        "geoFence": fence,
        "groundStation": "Skyhive",
        "mission": {
            "cruiseSpeed": 15,
            "firmwareType": 12,
            "hoverSpeed": 5,
            "items": [],
            "plannedHomePosition": [*home[:2], 0] if home else [0, 0, 0],
            "vehicleType": 2,
            "version": 2,
        },
        "rallyPoints": {"points": [], "version": 2},
        "version": 1,
    }


def drone_envelope(drone: Drone) -> env.Envelope:
    return organisation_envelope(drone.organisation).restricted(
        drone.max_height, drone.max_distance
    )


def _plan_body(body: Mapping[str, Any]) -> tuple[dict, list | None]:
    """A QGroundControl `.plan` file becomes its geoFence with the default limits; its
    planned home must lie inside the inclusion fence."""
    if body.get("fileType") != "Plan":
        return dict(body), body.get("home")
    mission = body.get("mission") if isinstance(body.get("mission"), dict) else {}
    return {"geoFence": body.get("geoFence")}, mission.get("plannedHomePosition")


def set_envelope(organisation: Organisation, body: Any) -> env.Envelope:
    """Validate and store a new envelope, then send it to the organisation's drones.

    Raises EnvelopeError naming the field; the stored envelope is then left unchanged.
    """
    if not isinstance(body, Mapping):
        raise env.EnvelopeError("envelope", "must be a JSON object")
    limits, home = _plan_body(body)
    if home is not None:
        home = list(env.parse_latlon(home, "home"))
    envelope = env.parse_envelope(limits, home=home)
    stored = {**envelope.to_dict(), **({"home": home} if home else {})}
    Organisation.objects.filter(pk=organisation.pk).update(envelope=stored)
    organisation.envelope = stored
    envelope_changed.send(sender=Organisation, organisation=organisation, envelope=stored)
    drones = Drone.objects.filter(organisation=organisation).select_related("organisation")
    transaction.on_commit(lambda: send_to_drones(list(drones)))
    return envelope


def send_to_drones(drones: Iterable[Drone]) -> None:
    """Queue each drone's own envelope on `<id>/envelope/in`, with its Remote ID identity
    and its log collection mode."""
    for drone in drones:
        message = protocol.EnvelopeUpdate(
            drone_envelope(drone).to_dict(),
            remote_id=identity_for(drone),
            log_collection=drone.log_collection,
        )
        outbox.send_to_drone(drone.drone_id, "envelope", message.to_dict(), ttl=ENVELOPE_TTL_S)


def send_when_online(sender: object, drone_ids: Sequence[str] = (), **kwargs: object) -> None:
    """drones_came_online receiver: a drone back online gets its envelope again, and its
    last target is forgotten (it may have restarted)."""
    drones = list(Drone.objects.filter(drone_id__in=list(drone_ids)).select_related("organisation"))
    stale = [d.pk for d in drones if d.nav_target is not None]
    try:
        if stale:
            Drone.objects.filter(pk__in=stale).update(nav_target=None)
        send_to_drones(drones)
    except Exception:  # the heartbeat path must not fail on the outbox
        log.exception("could not queue envelopes for %s", list(drone_ids))


# -- where a drone is and is going ----------------------------------------------------------


def home_of(drone: Drone) -> tuple[float, float] | None:
    """Where the drone took off from: its position while at rest, else the remembered one."""
    if not drone.airborne and drone.lat is not None and drone.lon is not None:
        return drone.lat, drone.lon
    if drone.home:
        return float(drone.home[0]), float(drone.home[1])
    return None if drone.lat is None or drone.lon is None else (drone.lat, drone.lon)


def position_ned(drone: Drone, home: Sequence[float] | None) -> env.NED | None:
    if home is None or drone.lat is None or drone.lon is None:
        return None
    north, east = env.latlon_to_ne(drone.lat, drone.lon, home)
    return north, east, -(drone.alt or 0.0)


def current_target(drone: Drone, home: Sequence[float] | None) -> env.NED | None:
    """The last target the drone accepted while airborne, else its reported position."""
    if drone.airborne and drone.nav_target and len(drone.nav_target) == 3:
        return tuple(float(v) for v in drone.nav_target)  # type: ignore[return-value]
    return position_ned(drone, home)


def rise_under_way(drone: Drone) -> float | None:
    """Metres a drone in the air still climbs (+) or descends (-) to the height of the last
    target it accepted, when more than the vertical tolerance: a sideways command sent now
    is flown from its height on a slant to the target at that height (onboard/navigation.py
    adds it to the last target). The airspace checks it so too (airspace/separation.py)."""
    target = drone.nav_target
    if not drone.airborne or drone.alt is None or not isinstance(target, list | tuple):
        return None
    if len(target) != 3 or not isinstance(target[2], int | float):
        return None
    rise = -float(target[2]) - float(drone.alt)
    return rise if abs(rise) > settings.AIRSPACE_VERTICAL_TOLERANCE_M else None


def drone_pace(drone: Drone) -> Paced:
    """How fast the drone is assumed to fly and climb, as the airspace assumes it (named in
    settings.AIRSPACE_PACE, not imported: airspace sits above fleet)."""
    return import_string(settings.AIRSPACE_PACE)(drone)


def climbing_from(drone: Drone) -> float | None:
    """The height of a drone in the air still climbing to its last target (rise_under_way),
    from which a sideways leg sent now is flown on a slant; None when it is not climbing."""
    rise = rise_under_way(drone)
    return None if rise is None or rise <= 0 else float(drone.alt or 0.0)


def command_climb(drone: Drone, command: str, params: Mapping[str, Any]) -> Climb | None:
    """A sideways command sent while the drone still climbs: flown on a slant from the
    height it is at now (terrain/climbout.py), which its terrain clearance and the
    published zones are checked on. The climb began under its last target (a climb in
    place), the ground the terrain's climb-out rule compares with."""
    height = climbing_from(drone)
    if command not in env.HORIZONTAL_COMMANDS or height is None:
        return None
    speed = params.get("speed")
    slope = climb_slope(drone_pace(drone), speed and float(speed))
    column = current_target(drone, home_of(drone))
    return Climb(height, slope, None if column is None else (column[0], column[1]))


def _battery_percent(drone: Drone) -> float | None:
    return None if drone.battery_remaining is None else drone.battery_remaining * 100.0


def check_command(
    drone: Drone, command: str, params: Mapping[str, Any], confirmed: bool = False
) -> list[dict]:
    """Raise OutsideEnvelope when the command's move (or its leg) breaks the drone's
    envelope, NeedsConfirmation when it goes beyond the defaults unconfirmed. Returns where
    the move's terrain clearance could not be checked (terrain/guard.py)."""
    home = home_of(drone)
    here = position_ned(drone, home)
    base = current_target(drone, home)
    move = env.resolve(command, params, base, here, home)
    if move is None:
        return []
    horizontal = command in env.HORIZONTAL_COMMANDS
    move = env.Move(move.kind, move.ned, horizontal)
    envelope = drone_envelope(drone)
    climb = command_climb(drone, command, params)
    warnings: list[dict] = []
    # From the last target (the planned leg) and, while the drone is still on its way
    # there, from where it is: it turns to the new target at once (the agent's own check,
    # onboard/envelope.py command_starts).
    for start in env.command_starts(base, here):
        violation, found = _leg_violation(drone, envelope, home, move, start, climb)
        if violation is not None:
            raise OutsideEnvelope(violation)
        warnings = warnings or found
    beyond = None if confirmed else env.beyond_defaults(move)
    if beyond is not None:
        raise NeedsConfirmation(beyond)
    # Separation from the other drones' reserved airspace (airspace/separation.py).
    import_string(settings.AIRSPACE_COMMAND_CHECK)(drone, command, params)
    return warnings


def _leg_violation(
    drone: Drone,
    envelope: env.Envelope,
    home: Sequence[float] | None,
    move: env.Move,
    start: env.NED | None,
    climb: Climb | None,
) -> tuple[env.Violation | None, list[dict]]:
    """The envelope's, the published zones' or the terrain's refusal of the leg from
    `start` (the first that refuses), and where its terrain could not be checked."""
    violation = env.check(envelope, home, move, drone.airborne, _battery_percent(drone), start)
    violation = violation or published_zones("move")(
        drone.organisation, home, move, start, drone.airborne, climb=climb
    )
    assessed = terrain.move_assessment(
        drone.organisation_id, home, start, move, ceiling=envelope.max_height, climb=climb
    )
    return violation or assessed.violation, assessed.warnings


def step_violations(
    organisation: Organisation,
    steps: Sequence[Mapping[str, Any]],
    drone: Drone | None = None,
    home: Sequence | None = None,
    fence: Mapping | None = None,
) -> list[env.StepViolation]:
    """Every step of a mission that breaks the envelope: flown by `drone` from where it is,
    or, before a drone is chosen, from the ground at `home` (else plan_home). `fence` (a
    QGroundControl geoFence, e.g. an imported plan's own) applies on top."""
    if drone is not None:
        home = home_of(drone)
        envelope = with_fence(drone_envelope(drone), fence)
        start, airborne = current_target(drone, home), drone.airborne
        found = env.step_violations(envelope, home, steps, start, airborne, _battery_percent(drone))
    else:
        home = home if home is not None else plan_home(organisation, steps)
        envelope = with_fence(organisation_envelope(organisation), fence)
        start, airborne = (0.0, 0.0, 0.0), False
        found = env.step_violations(envelope, home, steps, start, airborne, None)
    # The legs flown while a climb is under way at the drone's pace, else the settings';
    # a drone still climbing when the mission starts flies its first leg on that climb.
    pace = drone_pace(drone) if drone is not None else None
    rising = climbing_from(drone) if drone is not None else None
    found += published_zones("steps")(
        organisation, home, steps, start, airborne, pace=pace, climbing_from=rising
    )
    found += terrain.step_violations(
        organisation.pk, home, steps, start, envelope.max_height, pace, climbing_from=rising
    )
    return sorted(found, key=lambda v: v.index)


def published_zones(check: str) -> Callable:
    """The published zones' check named `check` (settings.PUBLISHED_ZONE_CHECKS: the zones
    app builds on this one, so it is named there rather than imported)."""
    return import_string(settings.PUBLISHED_ZONE_CHECKS[check])


def with_fence(envelope: env.Envelope, fence: Mapping | None) -> env.Envelope:
    """The envelope with a mission's own geoFence (QGroundControl shape) on top."""
    if not fence:
        return envelope
    polygons, circles = env.parse_geofence(fence)
    return replace(
        envelope, polygons=envelope.polygons + polygons, circles=envelope.circles + circles
    )


def check_steps(
    drone: Drone, steps: Sequence[Mapping[str, Any]], fence: Mapping | None = None
) -> None:
    """Raise OutsideEnvelope naming the first mission step the drone may not fly (within
    `fence` too: a mission's own geoFence)."""
    found = step_violations(drone.organisation, steps, drone, fence=fence)
    if found:
        raise OutsideEnvelope(found[0].violation, found[0].index)


def steps_beyond_defaults(
    organisation: Organisation,
    steps: Sequence[Mapping[str, Any]],
    drone: Drone | None = None,
    home: Sequence | None = None,
) -> list[env.StepViolation]:
    """Every step going beyond the envelope's defaults, walked as step_violations does."""
    if drone is not None:
        home = home_of(drone)
        return env.steps_beyond_defaults(home, steps, current_target(drone, home))
    home = home if home is not None else plan_home(organisation, steps)
    return env.steps_beyond_defaults(home, steps, (0.0, 0.0, 0.0))


def terrain_warnings(
    organisation: Organisation,
    steps: Sequence[Mapping[str, Any]],
    drone: Drone | None = None,
    home: Sequence | None = None,
) -> list[dict]:
    """Where the terrain clearance of a mission could not be checked (no terrain, voids),
    walked as step_violations does."""
    if drone is not None:
        home = home_of(drone)
        return terrain.plan_warnings(organisation.pk, home, steps, current_target(drone, home))
    home = home if home is not None else plan_home(organisation, steps)
    return terrain.plan_warnings(organisation.pk, home, steps, (0.0, 0.0, 0.0))


def confirm_steps(
    organisation: Organisation,
    steps: Sequence[Mapping[str, Any]],
    drone: Drone | None = None,
    home: Sequence | None = None,
) -> None:
    """Raise NeedsConfirmation naming the first step beyond the defaults."""
    found = steps_beyond_defaults(organisation, steps, drone, home)
    if found:
        raise NeedsConfirmation(found[0].violation, found[0].index)


def plan_home(organisation: Organisation, steps: Sequence[Mapping[str, Any]]) -> list | None:
    """A mission's home before a drone is chosen: the envelope's home, else the first
    navigate target (missions are flown from near their first waypoint)."""
    stored = (organisation.envelope or {}).get("home")
    if stored:
        return list(stored)
    for step in steps:
        if step["command"] == "navigate":
            return [step["params"]["lat"], step["params"]["lon"]]
    return None


def check_plan(
    organisation: Organisation,
    steps: Sequence[Mapping[str, Any]],
    home: Sequence | None = None,
    fence: Mapping | None = None,
) -> None:
    """Raise OutsideEnvelope for a mission whose steps break the organisation's envelope
    (and `fence`), flown from the ground at `home` (or plan_home)."""
    found = step_violations(organisation, steps, home=home, fence=fence)
    if found:
        raise OutsideEnvelope(found[0].violation, found[0].index)


def moves_target(command: str, reply: Mapping[str, Any] | None) -> bool:
    """The drone accepted a navigation command and said where it now flies."""
    if not reply or not reply.get("ok") or command not in protocol.NAVIGATION_COMMANDS:
        return False
    return isinstance((reply.get("result") or {}).get("target"), dict)


def remember_target(drone: Drone, command: str, reply: Mapping[str, Any] | None) -> None:
    """After the drone accepted a navigation command: its new target, and its home."""
    if not moves_target(command, reply):
        return
    target = reply["result"]["target"]  # type: ignore[index]
    ned = [target.get("north"), target.get("east"), target.get("down")]
    fields = {"nav_target": ned}
    if command == "takeoff" and drone.lat is not None and not drone.airborne:
        fields["home"] = [drone.lat, drone.lon]
    Drone.objects.filter(pk=drone.pk).update(**fields)
    # The accepted leg becomes the drone's reservation (airspace/separation.py).
    import_string(settings.AIRSPACE_COMMAND_RESERVE)(drone, command, reply)


def forget_target(drone: Drone) -> None:
    """A mission moves the drone without the ground knowing its targets: fall back to its
    reported position."""
    Drone.objects.filter(pk=drone.pk).update(nav_target=None)
