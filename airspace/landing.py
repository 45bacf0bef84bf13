"""The landing queue over home: several drones sent home to one landing site come down one
at a time, never through each other (docs/airspace.md, "Landing queue").

- A **site** is a drone's home; drones whose homes are within the horizontal separation
  minimum of each other share one.
- **Sending a drone home** (`send_home`: the operator's `return`, a mission stopped with a
  return) when no other drone of the airspace is queued at the site (holding over it or
  landing there) and none is in the air over it below this one: it is sent home as
  before (home at its height, then down) and counts as landing there.
- Otherwise it **joins the queue**: it holds over its home at a **layer**, the lowest
  height at or above its current one (its height, then higher by `layer_step`) whose band
  is the vertical minimum clear of every other queued drone's layer and of every other
  drone in the air over the site, no higher than its envelope ceiling; with none clear it
  holds at its height. The hold is a `navigate` to home at that layer, checked by the
  flight envelope as every command is.
- **Order**, first come first served: the queue (`advance`, a periodic task) gives `land`
  to the first drone in order of joining that is over its home and has no other drone in
  the air under it within the minima (nothing comes down through another drone), once
  the drone before it that was landing is on the ground.
- **Keeping to the hold**: a holding drone that for `AIRSPACE_LANDING_HOLD_RESEND_S`
  neither was at its hold nor came `AIRSPACE_LANDING_OVER_HOME_M` nearer to it is sent
  its hold again (`keep_to_hold`), at most once per that time and
  `AIRSPACE_LANDING_HOLD_RESENDS` times per queue place.
- **Leaving**: a drone on the ground (landed there or elsewhere), offline, or given
  another plan (a command that moves it, a mission, the operator's `hold`) leaves the
  queue; so does one that refused its hold or did not fly it after every re-send. A
  queue never waits for a drone that left it.
- **A drone flying a mission** sent home by the operator has its mission parts stopped
  first (settings.AIRSPACE_RETURN_STOPS_MISSION), in the same transaction.
- Each queued drone's reservation is its way to the hold, the hold, then its way down.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from django.conf import settings
from django.db import transaction
from django.db.models import Q
from django.utils import timezone
from django.utils.module_loading import import_string

from fleet import envelopes
from fleet.models import Drone, Organisation
from onboard import protocol
from workers import outbox

from . import reservations
from .corridors import ground_distance
from .models import LandingSlot

log = logging.getLogger(__name__)

QUEUE_COMMAND = reservations.LANDING_QUEUE
# A queue's navigate is its hold when it flies to the site within this much.
_SAME_POINT_M = 0.5


@dataclass(frozen=True)
class Queued:
    """A drone's place in its site's queue (1: next to land) and its holding layer."""

    place: int
    layer_m: float
    site: tuple[float, float]

    def as_result(self) -> dict:
        return {"place": self.place, "layer_m": round(self.layer_m, 1), "site": list(self.site)}


# -- who is where -------------------------------------------------------------------------


def _scope(organisation_id: int) -> Q:
    return Q() if settings.AIRSPACE_SITE_WIDE else Q(organisation_id=organisation_id)


def _minima(organisation_id: int) -> tuple[float, float]:
    return reservations.minima_for(organisation_id)


def _near(lat: float, lon: float, site: Sequence[float], within: float) -> bool:
    return ground_distance(lat, lon, site[0], site[1]) < within


def site_slots(organisation_id: int, site: Sequence[float], exclude: int | None = None) -> list:
    """The active slots at the site (homes within the horizontal minimum), in joining order."""
    horizontal = _minima(organisation_id)[0]
    rows = (
        LandingSlot.objects.filter(_scope(organisation_id), ended_at__isnull=True)
        .exclude(drone_id=exclude)
        .select_related("drone")
        .order_by("joined_at", "pk")
    )
    return [s for s in rows if _near(s.site_lat, s.site_lon, site, horizontal)]


def over_site(organisation_id: int, site: Sequence[float], exclude: Iterable[int]) -> list[Drone]:
    """The other drones of the airspace in the air over the site (within the horizontal
    minimum of it), from their reported positions."""
    horizontal = _minima(organisation_id)[0]
    drones = Drone.objects.filter(
        _scope(organisation_id), airborne=True, online=True, lat__isnull=False
    ).exclude(pk__in=list(exclude))
    return [d for d in drones if _near(d.lat, d.lon, site, horizontal)]


def _below(drones: Iterable[Drone], height: float, vertical: float) -> list[Drone]:
    return [d for d in drones if (d.alt or 0.0) < height + vertical]


# -- layers -------------------------------------------------------------------------------


def holding_layer(
    height: float,
    taken: Iterable[float],
    step: float,
    vertical: float,
    ceiling: float,
    over_site: bool = False,
) -> float:
    """The lowest height at or above `height` (then higher by `step`) whose band is the
    vertical minimum clear of every height `taken`: a drone holding at h keeps
    h ± the vertical tolerance, so two holds are clear when `step` apart (layer_step).
    No higher than `ceiling`. A drone already over the site climbs straight up, so it
    never climbs through a height taken there. With none clear, `height` itself."""
    taken = list(taken)
    clear = max(step, vertical)
    layer = height
    while layer <= ceiling + 1e-6:
        if over_site and any(height < other < layer for other in taken):
            break
        if all(abs(layer - other) >= clear - 1e-6 for other in taken):
            return layer
        layer += step
    return height


def _layer_step(organisation_id: int) -> float:
    vertical = _minima(organisation_id)[1]
    return vertical + 2 * settings.AIRSPACE_VERTICAL_TOLERANCE_M


# -- joining ------------------------------------------------------------------------------


def send_home(drone: Drone) -> Queued | None:
    """Send an airborne drone home through its site's queue: None when the site is free
    (it goes home as before, counted as landing there), else its place and layer (the
    caller sends `hold_command`). Its reservation is made here."""
    home, here = envelopes.home_of(drone), reservations.position_of(drone)
    if not drone.airborne or home is None or here is None:
        return None
    with transaction.atomic():
        reservations.lock(drone.organisation_id)
        LandingSlot.objects.filter(drone=drone, ended_at__isnull=True).update(
            ended_at=timezone.now(), end_reason="sent home again"
        )
        queue = site_slots(drone.organisation_id, home, exclude=drone.pk)
        around = over_site(drone.organisation_id, home, [drone.pk])
        vertical = _minima(drone.organisation_id)[1]
        if not queue and not _below(around, here[2], vertical):
            _reserve_way_home(drone, home)
            _join(drone, home, here[2], LandingSlot.State.LANDING)
            return None
        ceiling = envelopes.drone_envelope(drone).max_height
        queued = {s.drone_id for s in queue}
        # Queued drones are taken at their layers (where they hold), the others where they are.
        taken = [s.layer_m for s in queue] + [d.alt or 0.0 for d in around if d.pk not in queued]
        horizontal = _minima(drone.organisation_id)[0]
        step = _layer_step(drone.organisation_id)
        overhead = _near(here[0], here[1], home, horizontal)
        layer = holding_layer(here[2], taken, step, vertical, ceiling, overhead)
        _reserve_hold(drone, home, here[2], layer, queue)
        _join(drone, home, layer, LandingSlot.State.HOLDING)
        return Queued(len(queue) + 1, layer, (home[0], home[1]))


def _join(drone: Drone, home: Sequence[float], layer: float, state: str) -> LandingSlot:
    now = timezone.now()
    holding = state == LandingSlot.State.HOLDING
    # A holding drone is sent its hold now (by the caller): the watch of its way starts.
    away = _distance_to_hold(drone, home, layer) if holding else None
    return LandingSlot.objects.create(
        organisation_id=drone.organisation_id,
        drone=drone,
        site_lat=home[0],
        site_lon=home[1],
        layer_m=layer,
        state=state,
        landing_at=None if holding else now,
        hold_sent_at=now if holding else None,
        watched_at=now if holding else None,
        watched_m=away,
    )


def _distance_to_hold(drone: Drone, site: Sequence[float], layer: float) -> float | None:
    """How far the drone is from its hold (over the site at its layer), in metres."""
    if drone.lat is None or drone.lon is None:
        return None
    across = ground_distance(drone.lat, drone.lon, site[0], site[1])
    return math.hypot(across, (drone.alt or 0.0) - layer)


def hold_command(drone: Drone, queued: Queued) -> tuple[str, dict]:
    """The `navigate` that takes the drone to its hold: over home, at its layer (the
    altitude change from the height it was last sent to)."""
    home = envelopes.home_of(drone)
    target = envelopes.current_target(drone, home)
    height = -target[2] if target is not None else (drone.alt or 0.0)
    lat, lon = queued.site
    return "navigate", {"lat": lat, "lon": lon, "altitude_delta": queued.layer_m - height}


def _reserve_way_home(drone: Drone, home: Sequence[float]) -> None:
    steps = [{"command": "navigate", "params": {"lat": home[0], "lon": home[1]}}]
    reservations.reserve_steps(drone, [*steps, {"command": "land"}], QUEUE_COMMAND)


def _expected_wait_s(queue: Sequence[LandingSlot]) -> float:
    """How long the drones ahead take to come down, at the climb rate (the corridors'
    descent rate), stretched by the slack and each given the buffer."""
    climb = settings.AIRSPACE_CLIMB_SPEED_M_S
    slack, buffer = settings.AIRSPACE_TIME_SLACK, settings.AIRSPACE_TIME_BUFFER_S
    return sum(s.layer_m / climb * (1.0 + slack) + buffer for s in queue)


def _reserve_hold(
    drone: Drone, home: Sequence[float], height: float, layer: float, queue: Sequence
) -> None:
    """Its reservation: the way to the hold, the hold while the drones ahead land, then
    its way down."""
    steps = [
        {
            "command": "navigate",
            "params": {"lat": home[0], "lon": home[1], "altitude_delta": layer - height},
        },
        {"command": "sleep", "params": {"value": _expected_wait_s(queue)}},
        {"command": "land"},
    ]
    reservations.reserve_steps(drone, steps, QUEUE_COMMAND)


def is_queue_hold(drone: Drone, command: str, params: Mapping[str, Any]) -> bool:
    """The command is the drone's own hold in the queue (its site, its layer): the queue
    separates it from the other queued drones, so it is not checked against their
    reservations, and it keeps the queue's reservation."""
    if command != "navigate" or "lat" not in params or "lon" not in params:
        return False
    slot = LandingSlot.objects.filter(
        drone=drone, ended_at__isnull=True, state=LandingSlot.State.HOLDING
    ).first()
    if slot is None:
        return False
    at = ground_distance(float(params["lat"]), float(params["lon"]), slot.site_lat, slot.site_lon)
    return at <= _SAME_POINT_M


def hold_after_stop(drone: Drone) -> None:
    """The drone's mission is being stopped: its hold over home is sent by the queue's
    pass once it reports no mission running (`keep_to_hold`), not with the stop, whose
    own hold where it is would override it."""
    LandingSlot.objects.filter(drone=drone, ended_at__isnull=True).update(
        hold_sent_at=None, watched_at=None
    )


def leave(drone: Drone, reason: str) -> None:
    """The drone leaves its queue (another plan, no answer)."""
    LandingSlot.objects.filter(drone=drone, ended_at__isnull=True).update(
        ended_at=timezone.now(), end_reason=reason[:80]
    )


# -- the operator's `return` (fleet/commands.py, through settings) ------------------------


def route_return(drone: Drone) -> tuple[str, dict, dict] | None:
    """AIRSPACE_RETURN_ROUTE: the operator's `return`. None when it is sent as it is,
    else the command to send instead (the hold), its params and the reply's `queue`
    result. A drone in the air has its mission parts stopped first, in the same
    transaction: an envelope refusal of the hold leaves no queue place behind and stops
    nothing."""
    stop_parts = import_string(settings.AIRSPACE_RETURN_STOPS_MISSION)
    with transaction.atomic():
        queued = send_home(drone)
        if queued is None:
            if drone.airborne:  # on the ground the drone refuses a return: nothing to stop
                stop_parts(drone, None)
            return None
        command, params = hold_command(drone, queued)
        envelopes.check_command(drone, command, params, confirmed=True)
        if stop_parts(drone, queued.as_result()):
            # Flying a mission: it is sent `hold` (its mission pauses where it is, at
            # once: no further step), and its hold over home once it reports no mission
            # running (keep_to_hold) — after the stop's own hold where it is, which would
            # otherwise override it.
            hold_after_stop(drone)
            command, params = "hold", {}
    return command, params, queued.as_result()


def return_answered(drone: Drone, command: str, reply: Mapping[str, Any] | None) -> None:
    """AIRSPACE_RETURN_ANSWERED: the drone's answer to a `return` (or its hold) or a
    `hold`. A refused return leaves the queue, and so does an unanswered one sent as
    before; an unanswered hold stays (the queue sends it again when the drone does not
    fly it: `keep_to_hold`); an operator's hold is another plan."""
    if command == "hold":
        if reply and reply.get("ok"):
            leave(drone, "commanded otherwise")
        return
    active = LandingSlot.objects.filter(drone=drone, ended_at__isnull=True)
    holding = active.filter(state=LandingSlot.State.HOLDING)
    if reply is None:
        if not holding.exists():
            leave(drone, "no answer to the return")
    elif not reply.get("ok"):
        leave(drone, "the return was refused")
    else:
        holding.filter(hold_sent_at__isnull=False).update(hold_accepted_at=timezone.now())


# -- the queue's turns (a periodic task) ----------------------------------------------------


def _gone(slot: LandingSlot) -> str | None:
    drone = slot.drone
    if not drone.online:
        return "disconnected"
    if drone.airborne:
        return None
    horizontal = _minima(slot.organisation_id)[0]
    if drone.lat is not None and _near(
        drone.lat, drone.lon, (slot.site_lat, slot.site_lon), horizontal
    ):
        return "landed"
    return "landed elsewhere"


def _sites(slots: Sequence[LandingSlot]) -> list[list[LandingSlot]]:
    """Slots grouped into sites: an airspace's slots whose homes are within the horizontal
    minimum of one another (transitively), each in joining order."""
    groups: list[list[LandingSlot]] = []
    for slot in slots:
        key = None if settings.AIRSPACE_SITE_WIDE else slot.organisation_id
        horizontal = _minima(slot.organisation_id)[0]
        joined = [
            g
            for g in groups
            if (None if settings.AIRSPACE_SITE_WIDE else g[0].organisation_id) == key
            and any(
                _near(slot.site_lat, slot.site_lon, (o.site_lat, o.site_lon), horizontal) for o in g
            )
        ]
        merged = [s for g in joined for s in g] + [slot]
        groups = [g for g in groups if not any(g is j for j in joined)] + [merged]
    return [sorted(g, key=lambda s: (s.joined_at, s.pk)) for g in groups]


def _over_home(slot: LandingSlot) -> bool:
    drone = slot.drone
    if drone.lat is None:
        return False
    at = ground_distance(drone.lat, drone.lon, slot.site_lat, slot.site_lon)
    return at <= settings.AIRSPACE_LANDING_OVER_HOME_M


def next_to_land(site: Sequence[LandingSlot]) -> LandingSlot | None:
    """The drone whose turn it is, or None: nothing while one is landing; else the first
    to have joined that is over its home with no other drone in the air under it."""
    if any(s.state == LandingSlot.State.LANDING for s in site):
        return None
    for slot in site:
        if not _over_home(slot):
            continue
        home = (slot.site_lat, slot.site_lon)
        around = over_site(slot.organisation_id, home, [slot.drone_id])
        if not any((d.alt or 0.0) < (slot.drone.alt or 0.0) for d in around):
            return slot
    return None


def _send_land(slot: LandingSlot) -> None:
    drone = slot.drone
    # Landing is never refused by the envelope; the check stays on every command's path.
    envelopes.check_command(drone, "land", {})
    outbox.send_to_drone(drone.drone_id, "control", protocol.control_request("land").to_dict())


def _land(slot: LandingSlot) -> None:
    reservations.reserve_steps(slot.drone, [{"command": "land"}], QUEUE_COMMAND)
    slot.state, slot.landing_at = LandingSlot.State.LANDING, timezone.now()
    slot.save(update_fields=["state", "landing_at"])
    transaction.on_commit(lambda: _send_land(slot))


def _resend_stale_land(slot: LandingSlot) -> None:
    """A landing drone still in the air long after its `land` (a lost message) gets it
    again; a return sent as before is left to the drone."""
    if slot.landing_at is None:
        return
    age = (timezone.now() - slot.landing_at).total_seconds()
    if age >= settings.AIRSPACE_LANDING_RESEND_S and _over_home(slot):
        LandingSlot.objects.filter(pk=slot.pk).update(landing_at=timezone.now())
        transaction.on_commit(lambda: _send_land(slot))


# -- keeping to the hold ----------------------------------------------------------------


def _at_hold(slot: LandingSlot) -> bool:
    """Near its hold: within twice the over-home tolerance of home and twice the vertical
    tolerance of its layer, where a drone that has its hold settles with room for its
    position's noise (a drone a little further out is not sent the hold again for it)."""
    drone = slot.drone
    if drone.lat is None:
        return False
    across = ground_distance(drone.lat, drone.lon, slot.site_lat, slot.site_lon)
    height = abs((drone.alt or 0.0) - slot.layer_m)
    return (
        across <= 2 * settings.AIRSPACE_LANDING_OVER_HOME_M
        and height <= 2 * settings.AIRSPACE_VERTICAL_TOLERANCE_M
    )


def _end(slot: LandingSlot, reason: str) -> None:
    slot.ended_at, slot.end_reason = timezone.now(), reason[:80]
    slot.save(update_fields=["ended_at", "end_reason"])


def _read_hold_reply(slot: LandingSlot) -> None:
    """The drone's answer to the hold the queue sent again, once it has come (through a
    gateway, as every reply): accepted, its target is the ground's again; refused, the
    drone leaves the queue."""
    if not slot.hold_request:
        return
    reply = outbox.reply_to(slot.hold_request)
    if reply is None:
        return
    slot.hold_request = ""
    if not reply.get("ok"):
        slot.save(update_fields=["hold_request"])
        _end(slot, f"its hold was refused: {reply.get('error') or 'no reason'}")
        return
    slot.hold_accepted_at = timezone.now()
    slot.save(update_fields=["hold_request", "hold_accepted_at"])
    envelopes.remember_target(slot.drone, "navigate", reply)


def keep_to_hold(slot: LandingSlot) -> None:
    """Send a holding drone its hold again when it does not fly it.

    The rule: a drone that during the last AIRSPACE_LANDING_HOLD_RESEND_S was neither at
    its hold nor came AIRSPACE_LANDING_OVER_HOME_M nearer to it is sent its hold again,
    at most once per that time and AIRSPACE_LANDING_HOLD_RESENDS times per queue place,
    after which it leaves the queue. What the drone flies is the judge, not whether it
    answered: a hold can be lost on the way, or accepted and then overridden (the hold
    of a mission stopped at the same time), while a hold flown whose answer was lost
    needs nothing — and must not be sent again, as its altitude change is relative to
    the drone's target. A refusal of the hold takes the drone out of the queue."""
    _read_hold_reply(slot)
    if slot.ended_at is not None:
        return
    now = timezone.now()
    away = _distance_to_hold(slot.drone, (slot.site_lat, slot.site_lon), slot.layer_m)
    if away is None:
        return
    if slot.hold_sent_at is None:
        if _stop_behind(slot, now):
            _send_hold(slot, now, away, again=False)
        return
    if slot.watched_at is None:
        return
    if (now - slot.watched_at).total_seconds() < settings.AIRSPACE_LANDING_HOLD_RESEND_S:
        return
    closing = settings.AIRSPACE_LANDING_OVER_HOME_M
    closer = slot.watched_m is not None and away <= slot.watched_m - closing
    if _at_hold(slot) or closer:
        # At it, or on its way: watched again from here.
        slot.watched_at, slot.watched_m = now, away
        slot.save(update_fields=["watched_at", "watched_m"])
        return
    if slot.hold_resends >= settings.AIRSPACE_LANDING_HOLD_RESENDS:
        log.warning("%s did not fly its hold after %d re-sends", slot.drone, slot.hold_resends)
        _end(slot, f"its hold was not flown after {slot.hold_resends} re-sends")
        return
    _send_hold(slot, now, away, again=True)


def _stop_behind(slot: LandingSlot, now: Any) -> bool:
    """A drone queued while flying a mission holds where it is until its heartbeat says no
    mission runs (its mission's stop, and the stop's own hold, are then behind it), or
    for AIRSPACE_LANDING_HOLD_RESEND_S should that not come."""
    waited = (now - slot.joined_at).total_seconds()
    return slot.drone.mission is None or waited >= settings.AIRSPACE_LANDING_HOLD_RESEND_S


def _send_hold(slot: LandingSlot, now: Any, away: float, again: bool) -> None:
    """The hold (again), checked by the flight envelope as every command is. The drone is
    not flying it, so its target is taken as where it is (the ground forgets the one it
    last accepted): the altitude change is from its reported height."""
    drone = slot.drone
    envelopes.forget_target(drone)
    drone.nav_target = None
    queued = Queued(0, slot.layer_m, (slot.site_lat, slot.site_lon))
    command, params = hold_command(drone, queued)
    try:
        envelopes.check_command(drone, command, params, confirmed=True)
    except envelopes.EnvelopeRefusal as exc:
        _end(slot, f"its hold was refused: {exc.message}")
        return
    request = protocol.control_request(command, params).to_dict()
    slot.hold_sent_at, slot.hold_request = now, request["request_id"]
    slot.hold_resends += 1 if again else 0
    slot.watched_at, slot.watched_m = now, away
    slot.save(
        update_fields=["hold_sent_at", "hold_request", "hold_resends", "watched_at", "watched_m"]
    )
    ttl = settings.AIRSPACE_LANDING_HOLD_RESEND_S
    drone_id = drone.drone_id
    transaction.on_commit(lambda: outbox.request_to_drone(drone_id, "control", request, ttl=ttl))


def advance() -> list[str]:
    """One pass of every queue: drones that left are taken out, then the next of each site
    is given `land`. The drones told to land."""
    landed: list[str] = []
    with transaction.atomic():
        rows = list(
            LandingSlot.objects.select_for_update(of=("self",))
            .filter(ended_at__isnull=True)
            .select_related("drone")
            .order_by("joined_at", "pk")
        )
        active = []
        for slot in rows:
            reason = _gone(slot)
            if reason is None:
                active.append(slot)
            else:
                LandingSlot.objects.filter(pk=slot.pk).update(
                    ended_at=timezone.now(), end_reason=reason
                )
        for site in _sites(active):
            for slot in site:
                if slot.state == LandingSlot.State.LANDING and slot.drone.airborne:
                    _resend_stale_land(slot)
                elif slot.state == LandingSlot.State.HOLDING and slot.drone.airborne:
                    keep_to_hold(slot)
            site = [s for s in site if s.ended_at is None]
            slot = next_to_land(site)
            if slot is not None:
                _land(slot)
                landed.append(slot.drone.drone_id)
    return landed


def queue_of(organisation: Organisation) -> list[LandingSlot]:
    """The organisation's active queue places, in joining order."""
    return list(
        LandingSlot.objects.filter(organisation=organisation, ended_at__isnull=True)
        .select_related("drone")
        .order_by("joined_at", "pk")
    )
