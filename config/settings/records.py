"""Flight records: when a disarmed flight is closed, which samples it reads, and what an
export may cost."""

from __future__ import annotations

from config.env import env

# A flight is closed this long after the heartbeat that showed it disarmed, so the
# telemetry of its last seconds (committed by the ingest in batches) is stored.
RECORDS_CLOSE_DELAY_S = env.float("RECORDS_CLOSE_DELAY_S", 5.0)
# Telemetry this far either side of the ground's arm and disarm times is read, and the
# drone's own FlightStatus samples in it set the flight's bounds: heartbeats come every
# HEARTBEAT_INTERVAL_S (5 s), so arming is known that late at most.
RECORDS_WINDOW_MARGIN_S = env.float("RECORDS_WINDOW_MARGIN_S", 6.0)
# A mission assignment or an arm/takeoff command this long before arming started the flight.
RECORDS_ATTRIBUTION_WINDOW_S = env.float("RECORDS_ATTRIBUTION_WINDOW_S", 120.0)
# Samples fetched per round trip while a flight is computed (memory stays bounded).
RECORDS_SAMPLE_BATCH = env.int("RECORDS_SAMPLE_BATCH", 5000)
# The beat's catch-up: flights missed by a lost heartbeat or task are opened or closed.
RECORDS_SETTLE_INTERVAL_S = env.float("RECORDS_SETTLE_INTERVAL_S", 30.0)
# A logbook's CSV export holds at most this many flights (newest first).
RECORDS_EXPORT_MAX_ROWS = env.int("RECORDS_EXPORT_MAX_ROWS", 10000)
# A logbook's PDF export holds at most this many flights, a page each (built in memory,
# a few kilobytes a page).
RECORDS_PDF_MAX_FLIGHTS = env.int("RECORDS_PDF_MAX_FLIGHTS", 500)
# A drone offline this long while armed is taken as lost: its flight is recorded up to its
# last heartbeat, with a `lost` event.
RECORDS_LOST_AFTER_S = env.float("RECORDS_LOST_AFTER_S", 600.0)
