"""Fleet happenings other apps react to, without the fleet app importing them."""

from django.dispatch import Signal

# Sent by the Drone Identifier after drones that were offline sent a heartbeat.
# Arguments: organisation_ids (set[int]), drone_ids (list[str]).
drones_came_online = Signal()

# Sent by the offline sweep after it marked drones offline. Arguments: drone_ids (list[str]).
drones_went_offline = Signal()

# Sent after an organisation's envelope was stored. Arguments: organisation, envelope (dict).
envelope_changed = Signal()
