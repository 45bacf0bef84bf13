"""The Drone Identifier: who is connected, where, with what.

Plain functions the gateway calls per message, and the offline sweep the Celery beat
runs. Each returns None when the message was taken, or a short reason when it was
dropped (the gateway counts it as `dropped.<reason>`).
"""

from __future__ import annotations

import json
import logging
import threading
import time
from concurrent import futures
from datetime import datetime, timedelta

from django.conf import settings
from django.db import DatabaseError, InterfaceError, OperationalError, connection, transaction
from django.utils import timezone

from onboard.protocol import GearAnnouncement, GearReply, Heartbeat
from workers import outbox

from . import events
from .models import ConnectionEvent, Drone
from .signals import (
    drones_arming_changed,
    drones_came_online,
    drones_went_offline,
    remote_id_failing,
    wind_return,
)

log = logging.getLogger(__name__)

# A drone clock further than this from the ground's is shown as not trusted.
CLOCK_TOLERANCE_S = 5.0

# One statement for a whole batch: update each drone's state and learn whether it was
# offline before (`old` reads the rows under lock, before the update), so reconnections
# are noticed without another round trip on the hot path. The rows travel as one JSON
# parameter: the statement's text never changes (psycopg parses it once) and the
# parameter is one C-encoded string, whatever the batch's size. Revoked drones are not
# updated: they are unknown here. A drone at rest with a position is at its home: the
# place it last stood on the ground is where it took off from once it flies (a mission's
# take-off tells the ground nothing else), and where a return brings it back.
_HEARTBEATS_SQL = """
WITH v AS (
    SELECT * FROM jsonb_to_recordset(%s::jsonb) AS v(
        drone_id text, lat float8, lon float8, alt float8, voltage float8,
        remaining float8, armed boolean, airborne boolean, mode text, mission jsonb, fc jsonb
    )
), old AS (
    SELECT id, online, armed FROM fleet_drone
    WHERE drone_id IN (SELECT drone_id FROM v) AND NOT credentials_revoked
    ORDER BY id FOR UPDATE
)
UPDATE fleet_drone AS d SET
    online = TRUE, last_seen = %s, lat = v.lat, lon = v.lon, alt = v.alt,
    battery_voltage = v.voltage, battery_remaining = v.remaining, armed = v.armed,
    airborne = v.airborne, flight_mode = v.mode, mission = v.mission, fc = v.fc,
    home = CASE WHEN NOT v.airborne AND v.lat IS NOT NULL AND v.lon IS NOT NULL
        THEN jsonb_build_array(v.lat, v.lon) ELSE d.home END
FROM v, old
WHERE d.drone_id = v.drone_id AND d.id = old.id
RETURNING d.drone_id, d.id, d.organisation_id, old.online, old.armed, d.armed
"""


def _row(heartbeat: Heartbeat, seen: datetime) -> dict:
    position = heartbeat.position
    mission = heartbeat.mission
    return {
        "drone_id": heartbeat.drone_id,
        "lat": None if position is None else position.lat,
        "lon": None if position is None else position.lon,
        "alt": None if position is None else position.alt,
        "voltage": heartbeat.battery_voltage,
        "remaining": heartbeat.battery_remaining,
        "armed": heartbeat.armed,
        "airborne": heartbeat.airborne,
        "mode": heartbeat.flight_mode[:40],
        "mission": None if mission is None else mission.to_dict(),
        "fc": fc_state(heartbeat, seen),
    }


def fc_state(heartbeat: Heartbeat, seen: datetime) -> dict:
    """The flight controller's link, and how far the drone's clock is from the ground's
    (its heartbeat's time against arrival; heartbeats are never queued, QoS 0). A clock
    off by more than CLOCK_TOLERANCE_S is shown as not trusted: the drone judges the age of
    requests through the offset it learns, so it still acts on them."""
    offset = round(heartbeat.ts - seen.timestamp(), 1)
    return {
        "protocol": heartbeat.fc_protocol,
        "connected": heartbeat.fc_connected,
        "clock_offset_s": offset,
        "clock_trusted": abs(offset) <= CLOCK_TOLERANCE_S,
        # What the drone says must change on its flight controller before it can fly.
        "setup": list(heartbeat.fc_setup),
        # Its Remote ID broadcast's health (fleet/airworthiness.py reads it), when known.
        **({} if heartbeat.remote_id is None else {"remote_id": heartbeat.remote_id.to_dict()}),
        # The flight controller's wind estimate and the drone's limit (fleet/wind.py).
        **({} if heartbeat.wind is None else {"wind": heartbeat.wind.to_dict()}),
        # The pack's serial as the flight controller reports it (batteries.fitting).
        **(
            {} if heartbeat.battery_serial is None else {"battery_serial": heartbeat.battery_serial}
        ),
    }


class _Throttle:
    """At most one live update per drone per interval; state changes always go through."""

    def __init__(self) -> None:
        self._last: dict[str, float] = {}
        self._lock = threading.Lock()

    def allow(self, drone_id: str, *, force: bool = False) -> bool:
        now = time.monotonic()
        with self._lock:
            if not force and now - self._last.get(drone_id, -1e9) < settings.FLEET_PUSH_INTERVAL_S:
                return False
            self._last[drone_id] = now
            return True


_throttle = _Throttle()


def live_state(heartbeat: Heartbeat, seen: datetime) -> dict:
    """The fields a fleet page shows, in the shape of the drone API."""
    return {
        "drone_id": heartbeat.drone_id,
        "online": True,
        "last_seen": seen.isoformat(),
        "position": None if heartbeat.position is None else heartbeat.position.to_dict(),
        "battery": {
            "voltage": heartbeat.battery_voltage,
            "remaining": heartbeat.battery_remaining,
        },
        "armed": heartbeat.armed,
        "airborne": heartbeat.airborne,
        "flight_mode": heartbeat.flight_mode,
        "mission": None if heartbeat.mission is None else heartbeat.mission.to_dict(),
        "fc": fc_state(heartbeat, seen),
    }


def handle_heartbeat(drone_id: str, heartbeat: Heartbeat) -> str | None:
    """Record one heartbeat (see handle_heartbeats)."""
    return handle_heartbeats([(drone_id, heartbeat)])[0]


def handle_heartbeats(batch: list[tuple[str, Heartbeat]]) -> list[str | None]:
    """Record heartbeats with one UPDATE; an `online` event for each drone that was offline.

    Only the newest heartbeat of a drone in the batch is written (the older ones would be
    overwritten in the same instant). Returns, per heartbeat, None or why it was dropped.
    """
    seen = timezone.now()
    reasons: list[str | None] = [None] * len(batch)
    latest: dict[str, Heartbeat] = {}
    for i, (drone_id, heartbeat) in enumerate(batch):
        if heartbeat.drone_id != drone_id:
            reasons[i] = "drone_id_mismatch"
        else:
            latest[drone_id] = heartbeat
    if not latest:
        return reasons
    rows, refused = _store_splitting(list(latest.values()), seen)
    stored = {drone_id for drone_id, *_ in rows}
    for i, (drone_id, _heartbeat) in enumerate(batch):
        if reasons[i] is None and drone_id in refused:
            reasons[i] = "db_rejected"
        elif reasons[i] is None and drone_id not in stored:
            reasons[i] = "unknown_drone"
    _announce(rows, latest, seen)
    return reasons


def _store_splitting(heartbeats: list[Heartbeat], seen: datetime) -> tuple[list, set[str]]:
    """`_store`, halving the batch while the database refuses it, so a heartbeat it cannot
    take costs only its own drone's update: (rows updated, drone ids refused)."""
    try:
        return _store(heartbeats, seen), set()
    except (OperationalError, InterfaceError):
        raise  # the database is away: the gateway retries the whole batch
    except (DatabaseError, UnicodeEncodeError) as exc:
        if len(heartbeats) == 1:
            log.error("heartbeat of %s refused by the database: %s", heartbeats[0].drone_id, exc)
            return [], {heartbeats[0].drone_id}
    half = len(heartbeats) // 2
    first_rows, first_refused = _store_splitting(heartbeats[:half], seen)
    rows, refused = _store_splitting(heartbeats[half:], seen)
    return first_rows + rows, first_refused | refused


def _store(heartbeats: list[Heartbeat], seen: datetime) -> list:
    """One UPDATE for the batch and the `online` events, in one transaction: a drone is
    never seen online without its event, and a batch the gateway retries after a lost
    connection is written whole or not at all."""
    rows = json.dumps([_row(heartbeat, seen) for heartbeat in heartbeats])
    with transaction.atomic():
        with connection.cursor() as cursor:
            cursor.execute(_HEARTBEATS_SQL, [rows, seen])
            rows = cursor.fetchall()
        came_online = [
            ConnectionEvent(
                drone_id=pk, kind=ConnectionEvent.Kind.ONLINE, at=seen, reason="heartbeat"
            )
            for _drone_id, pk, _org, was_online, *_armed in rows
            if not was_online
        ]
        if came_online:
            ConnectionEvent.objects.bulk_create(came_online)
    return rows


def _announce(rows: list, latest: dict[str, Heartbeat], seen: datetime) -> None:
    """Tell who listens: drones that came online, and the live fleet state (throttled)."""
    back = [(drone_id, org) for drone_id, _pk, org, was_online, *_armed in rows if not was_online]
    if back:
        drones_came_online.send(
            sender=ConnectionEvent,
            organisation_ids={org for _drone_id, org in back},
            drone_ids=[drone_id for drone_id, _org in back],
        )
    _announce_arming(rows, latest, seen)
    _announce_remote_id_failing(rows, latest, seen)
    _announce_wind_returns(rows, latest)
    for drone_id, _pk, organisation_id, was_online, *_armed in rows:
        if _throttle.allow(drone_id, force=not was_online):
            events.publish_nowait(
                organisation_id, {"type": "drone", "drone": live_state(latest[drone_id], seen)}
            )


def _announce_arming(rows: list, latest: dict[str, Heartbeat], seen: datetime) -> None:
    """Tell who listens (flight records) which drones armed or disarmed, once stored."""
    changes = [
        (pk, armed, seen, _mission_of(latest[drone_id]))
        for drone_id, pk, _org, _online, was_armed, armed in rows
        if armed != was_armed
    ]
    if not changes:
        return
    for receiver, outcome in drones_arming_changed.send_robust(sender=Drone, changes=changes):
        if isinstance(outcome, Exception):
            log.error("arming change not taken by %s: %s", receiver, outcome)


def _announce_wind_returns(rows: list, latest: dict[str, Heartbeat]) -> None:
    """Tell who listens (alerts) which drones the wind made return, with since when."""
    returning = [
        (drone_id, org, beat.wind.speed, beat.wind.limit, beat.wind.since)
        for drone_id, _pk, org, *_rest in rows
        if (beat := latest[drone_id]).wind is not None and beat.wind.action == "return"
    ]
    if not returning:
        return
    for receiver, outcome in wind_return.send_robust(sender=Drone, returning=returning):
        if isinstance(outcome, Exception):
            log.error("wind return not taken by %s: %s", receiver, outcome)


def _announce_remote_id_failing(rows: list, latest: dict[str, Heartbeat], seen: datetime) -> None:
    """Tell who listens (alerts) which airborne drones report a failing Remote ID."""
    failing = [
        (drone_id, org, beat.remote_id.error, seen)
        for drone_id, _pk, org, *_rest in rows
        if (beat := latest[drone_id]).airborne
        and beat.remote_id is not None
        and not beat.remote_id.ok
    ]
    if not failing:
        return
    for receiver, outcome in remote_id_failing.send_robust(sender=Drone, failing=failing):
        if isinstance(outcome, Exception):
            log.error("Remote ID failure not taken by %s: %s", receiver, outcome)


def _mission_of(heartbeat: Heartbeat) -> dict | None:
    return None if heartbeat.mission is None else heartbeat.mission.to_dict()


def handle_gear(drone_id: str, message: GearAnnouncement | GearReply) -> str | None:
    """Store announced specs and sensors; hand query replies to whoever asked."""
    fields = {}
    if message.specs is not None:
        fields["specs"] = message.specs
    if message.sensors is not None:
        fields["sensors"] = message.sensors
    # The database first: a retried message (database away) must still find its reply
    # waiting, and a reply is handed over only once.
    if fields:
        try:
            updated = Drone.objects.filter(drone_id=drone_id, credentials_revoked=False).update(
                **fields
            )
        except (OperationalError, InterfaceError):
            raise  # the database is away: the gateway retries
        except (DatabaseError, UnicodeEncodeError) as exc:
            log.error("gear of %s refused by the database: %s", drone_id, exc)
            return "db_rejected"
        if not updated:
            return "unknown_drone"
    if isinstance(message, GearReply):
        return outbox.deliver_reply(drone_id, message.request_id, message.to_dict())
    return None


def sweep_offline(now: datetime | None = None) -> list[str]:
    """Mark drones offline after the configured number of missed heartbeats.

    Compare-and-set per drone, so several sweeps (or a heartbeat arriving meanwhile) never
    write two offline events or undo a fresh heartbeat. Returns the drone ids marked.
    """
    now = now or timezone.now()
    grace = settings.OFFLINE_AFTER_MISSED_HEARTBEATS * settings.HEARTBEAT_INTERVAL_S
    threshold = now - timedelta(seconds=grace)
    stale = Drone.objects.filter(online=True, last_seen__lt=threshold).values_list(
        "pk", "drone_id", "organisation_id", "last_seen"
    )
    marked = []
    sent = []
    for pk, drone_id, organisation_id, last_seen in stale:
        if not Drone.objects.filter(pk=pk, online=True, last_seen=last_seen).update(online=False):
            continue
        silent = (now - last_seen).total_seconds()
        ConnectionEvent.objects.create(
            drone_id=pk,
            kind=ConnectionEvent.Kind.OFFLINE,
            at=now,
            reason=f"no heartbeat for {silent:.1f} s",
        )
        sent.append(
            events.publish_nowait(
                organisation_id,
                {"type": "drone", "drone": {"drone_id": drone_id, "online": False}},
            )
        )
        marked.append(drone_id)
    futures.wait([f for f in sent if f is not None], timeout=2)
    if marked:
        log.info("marked offline: %s", ", ".join(marked))
        drones_went_offline.send(sender=ConnectionEvent, drone_ids=marked)
    return marked
