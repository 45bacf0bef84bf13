"""What the checklists app tells apps above it (the audit trail) without importing them."""

from __future__ import annotations

from django.dispatch import Signal

# An admin changed a template or the organisation's rule: organisation_id, user, action,
# target, detail.
definition_changed = Signal()
