"""Pre-flight checklists (docs/checklists.md)."""

from __future__ import annotations

from config.env import env

# Whether an organisation that has not set its own rule needs a passed checklist before a
# manual flight or a mission start; each organisation's admins can change theirs.
CHECKLIST_REQUIRED_DEFAULT = env.bool("CHECKLIST_REQUIRED_DEFAULT", True)
# How long a passed checklist stays good for a flight, unless the organisation says otherwise.
CHECKLIST_VALID_MINUTES_DEFAULT = env.int("CHECKLIST_VALID_MINUTES_DEFAULT", 30)
# Live values older than this many seconds (a telemetry sample, a heartbeat) fail an item.
CHECKLIST_LIVE_MAX_AGE_S = env.float("CHECKLIST_LIVE_MAX_AGE_S", 30.0)
# At most this many items in one template, and this many templates per organisation.
CHECKLIST_MAX_ITEMS = env.int("CHECKLIST_MAX_ITEMS", 100)
CHECKLIST_MAX_TEMPLATES = env.int("CHECKLIST_MAX_TEMPLATES", 50)
# `fleet.commands` asks this function before an arm (or a take-off that arms): the fleet
# app names it here because it must not import the checklists app that builds on it.
FLIGHT_CHECKLIST_GATE = "checklists.gate.refusal"
# ... and this for the gate's read as annotations of the command's own drone lookup.
FLIGHT_CHECKLIST_LOOKUP = "checklists.gate.lookup_reads"
# The fleet table shows each drone's checklist state through this function (named here
# for the same reason).
FLEET_CHECKLIST_STATES = "checklists.gate.states_for"
