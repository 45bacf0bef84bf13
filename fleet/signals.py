"""Fleet happenings other apps react to, without the fleet app importing them."""

from typing import Any

from django.dispatch import Signal

# Sent by the Drone Identifier after drones that were offline sent a heartbeat.
# Arguments: organisation_ids (set[int]), drone_ids (list[str]).
drones_came_online = Signal()

# Sent by the offline sweep after it marked drones offline. Arguments: drone_ids (list[str]).
drones_went_offline = Signal()

# Sent by the Drone Identifier after heartbeats showed drones arming or disarming.
# Arguments: changes (list of (drone pk, armed: bool, seen: datetime, mission: dict | None)).
drones_arming_changed = Signal()

# Sent after an organisation's envelope was stored. Arguments: organisation, envelope (dict).
envelope_changed = Signal()

# Sent after an admin changed Remote ID identity (a drone's serial number or external
# module declaration, an organisation's operator registration), for the audit trail.
# Arguments: organisation_id (int), user, action (like "remote_id.drone"), target (str),
# changed (dict of the new values).
identity_changed = Signal()

# Sent after an operator changed one of a drone's settings (like its log collection
# mode), for the audit trail. Arguments: organisation_id (int), user, action (like
# "drone.log_collection"), target (the drone id), changed (dict of the new values).
drone_setting_changed = Signal()

# Sent by the Drone Identifier when heartbeats show airborne drones whose Remote ID
# reports a failure. Arguments: failing (list of (drone_id, organisation_id, error, seen)).
remote_id_failing = Signal()

# Sent by the Drone Identifier when heartbeats show drones the wind made return home
# (fleet/wind.py). Arguments: returning (list of (drone_id, organisation_id, speed m/s,
# limit m/s, since: epoch seconds or None)).
wind_return = Signal()

# Sent when a user's change was refused, for the audit trail. Arguments: organisation_id
# (int), user, action (like "mission.start"), target (str), reason (str).
action_refused = Signal()


def note_refusal(organisation_id: int, user: Any, action: str, target: object, reason: str) -> None:
    """Send action_refused: `user`'s `action` on `target` was refused for `reason`."""
    action_refused.send(
        None,
        organisation_id=organisation_id,
        user=user,
        action=action,
        target=str(target),
        reason=reason,
    )
