"""Maintenance: when a task counts as due soon, and the check airworthiness asks."""

from __future__ import annotations

from config.env import env

# A schedule is "due soon" once any trigger has used this share of its interval's last
# part: 0.1 warns at 90 h of a 100 h interval, or 329 days into a yearly inspection.
MAINTENANCE_DUE_SOON_FRACTION = env.float("MAINTENANCE_DUE_SOON_FRACTION", 0.1)
# fleet/airworthiness.py asks this for due maintenance (fleet cannot import the app that
# builds on it): given drones, it answers for each, in their order, a sentence naming each
# due item, or None.
MAINTENANCE_AIRWORTHINESS_CHECK = "maintenance.due.airworthiness_reasons"
# ... and this for the same check's read as annotations of the drone's own lookup (an arm's
# one statement), which lets the check above answer without a query when nothing is owed.
MAINTENANCE_AIRWORTHINESS_LOOKUP = "maintenance.due.lookup_reads"
# The beat looks at every drone with schedules this often for warnings that calendar time
# brings (flights bring theirs when recorded): a day's interval warns within the hour.
MAINTENANCE_WARN_INTERVAL_S = env.float("MAINTENANCE_WARN_INTERVAL_S", 3600.0)
