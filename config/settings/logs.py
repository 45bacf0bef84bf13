"""Flight logs: uploads, their stores, and the import workers' limits."""

from __future__ import annotations

from config.env import env

from .core import DATA_DIR

# Uploaded logs and their columnar stores, one folder per organisation and log.
LOGS_DIR = env.str("LOGS_DIR", f"{DATA_DIR}/logs")
# One upload's size; the body streams to disk (logs/asgi.py), never held in memory.
LOG_UPLOAD_MAX_BYTES = env.int("LOG_UPLOAD_MAX_BYTES", 2 * 1024**3)
# The Celery queue the import task goes to, served by workers of its own (docs/scaling.md):
# a 30-minute import never delays the fleet's work. Empty: the default queue.
LOGS_IMPORT_QUEUE = env.str("LOGS_IMPORT_QUEUE", "logs")
# What parses an uploaded file into its store (path, store directory, limits=, progress=).
LOGS_IMPORT_FUNCTION = env.str("LOGS_IMPORT_FUNCTION", "logs.store.import_to_store")
# ZIP archives (DFI): total uncompressed size and per-member compression ratio (ZIP bombs).
LOGS_MAX_UNCOMPRESSED_BYTES = env.int("LOGS_MAX_UNCOMPRESSED_BYTES", 2 * 1024**3)
LOGS_MAX_COMPRESSION_RATIO = env.float("LOGS_MAX_COMPRESSION_RATIO", 200.0)
# The most points one series request may ask for with `points` (min/max buckets).
LOGS_MAX_PLOT_POINTS = env.int("LOGS_MAX_PLOT_POINTS", 20_000)
# A log whose import stopped its worker (a crash, the kernel's OOM killer) this many times
# is marked failed instead of being delivered again.
LOGS_IMPORT_REDELIVERY_LIMIT = env.int("LOGS_IMPORT_REDELIVERY_LIMIT", 3)
# A running import shows it is alive this often; one silent for LOGS_STUCK_AFTER_S, or
# queued LOGS_UNSTARTED_AFTER_S ago and never started (its message lost), is retried or
# failed by the sweep, which runs every LOGS_SWEEP_INTERVAL_S.
LOGS_HEARTBEAT_INTERVAL_S = env.float("LOGS_HEARTBEAT_INTERVAL_S", 10.0)
LOGS_STUCK_AFTER_S = env.float("LOGS_STUCK_AFTER_S", 300.0)
LOGS_UNSTARTED_AFTER_S = env.float("LOGS_UNSTARTED_AFTER_S", 3600.0)
LOGS_SWEEP_INTERVAL_S = env.float("LOGS_SWEEP_INTERVAL_S", 60.0)
