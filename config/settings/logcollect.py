"""Logs the drones upload by themselves after landing (logs/collection.py): the size cap,
the chunk size, how many unfinished uploads one drone may hold, and how far a log's
flight may lie from a record's to be listed with it."""

from __future__ import annotations

from config.env import env

# One collected log, whole; an offer over it is refused before any byte is sent.
LOG_COLLECT_MAX_BYTES = env.int("LOG_COLLECT_MAX_BYTES", 512 * 1024**2)
# One chunk's body; within REQUEST_BODY_MAX_BYTES, the limit of every address not listed.
LOG_COLLECT_CHUNK_MAX_BYTES = env.int("LOG_COLLECT_CHUNK_MAX_BYTES", 512 * 1024)
# Unfinished uploads one drone may hold at once (their partial files count on disk); one
# unfinished this long is dropped with its bytes when the drone next offers a log.
LOG_COLLECT_MAX_OPEN = env.int("LOG_COLLECT_MAX_OPEN", 8)
LOG_COLLECT_ABANDONED_S = env.float("LOG_COLLECT_ABANDONED_S", 7 * 86400.0)
# A collected log belongs to the record whose arm-to-disarm span overlaps its own, with
# this much leeway for the drone's clock against the ground's.
LOG_COLLECT_ATTACH_MARGIN_S = env.float("LOG_COLLECT_ATTACH_MARGIN_S", 10.0)
# Where `manage.py run_simulated_drones` (make run) tells its drones to upload their logs:
# this ground's web address as the drones reach it.
LOG_COLLECT_GROUND_URL = env.str(
    "LOG_COLLECT_GROUND_URL", f"http://127.0.0.1:{env.int('WEB_PORT', 8000)}"
)
