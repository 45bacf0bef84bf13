"""What the batteries app tells apps above it (the audit trail) without importing them."""

from __future__ import annotations

from django.dispatch import Signal

# A member changed the organisation's retirement rules, named or re-rated a pack, or chose
# the pack a drone carries: organisation_id, user, action, target, changed
# ({field: [old, new]}). Sent inside the change's transaction, only once it is accepted.
changed = Signal()
