"""The health report of a flight log: its checks run at the end of the import, kept in
`checks.json` beside the log's store, and read back by the API and the viewer.

Thresholds are the defaults (`logs.checks.thresholds`) with the overrides of
settings.LOGS_CHECK_THRESHOLDS applied in this order: "*" (every organisation),
"*/airframe:<id>", "<organisation slug>", "<organisation slug>/airframe:<id>". The
airframe id is what the log records: PX4's SYS_AUTOSTART or ArduPilot's FRAME_CLASS.
"""

from __future__ import annotations

import json
import logging
import os
import uuid
from datetime import UTC, datetime
from pathlib import Path
from urllib.parse import quote

from django.conf import settings

from logs import trends
from logs.checks import ThresholdError, merged, run_checks
from logs.checks.base import LogView
from logs.models import FlightLog
from logs.store import LogStore

logger = logging.getLogger(__name__)

REPORT_VERSION = 1
AIRFRAME_PARAMETERS = ("SYS_AUTOSTART", "FRAME_CLASS")


def report_path(log: FlightLog) -> Path:
    return log.directory / "checks.json"


def airframe(store: LogStore) -> str | None:
    value = LogView(store).parameter(*AIRFRAME_PARAMETERS)
    return None if value is None else str(int(value))


def thresholds_for(log: FlightLog, store: LogStore) -> dict:
    """The thresholds for this log's organisation and airframe."""
    overrides = settings.LOGS_CHECK_THRESHOLDS or {}
    frame = airframe(store)
    slug = log.organisation.slug
    keys = ["*", f"*/airframe:{frame}", slug, f"{slug}/airframe:{frame}"]
    chosen = [overrides.get(k) for k in keys if frame is not None or "airframe" not in k]
    try:
        return merged(*chosen)
    except ThresholdError as exc:
        # The system check `logs.E001` names the bad entry when the site starts; a log
        # is still checked, with the defaults.
        logger.error("LOGS_CHECK_THRESHOLDS is refused (%s); checking with the defaults", exc)
        return merged()


def check(log: FlightLog, store: LogStore) -> dict:
    """Run every check on the log's store and keep the report (written atomically)."""
    report = {
        "version": REPORT_VERSION,
        "checked_at": datetime.now(UTC).isoformat(timespec="seconds"),
        "airframe": airframe(store),
        "checks": run_checks(store, thresholds_for(log, store)),
    }
    path = report_path(log)
    tmp = path.with_name(f".checks-{uuid.uuid4().hex}.json")
    tmp.write_text(json.dumps(report, allow_nan=False))
    os.replace(tmp, path)
    trends.record(log, report["checks"])
    return report


def report_of(log: FlightLog, store: LogStore) -> dict:
    """The kept report, or a fresh one for a log imported before checks existed (or whose
    report is unreadable)."""
    try:
        report = json.loads(report_path(log).read_text())
        if report.get("version") == REPORT_VERSION:
            return report
    except (OSError, ValueError):
        pass
    return check(log, store)


def viewer_link(log: FlightLog, result: dict) -> str:
    """The viewer at the check's moment, on its window, plotting its series (the page's
    address format: static/js/logs/permalink.js)."""
    parts = []
    if result.get("t") is not None:
        parts.append(f"t={result['t']:.3f}")
    window = result.get("window")
    if window:
        parts.append(f"view={window[0]:.3f}~{window[1]:.3f}")
    if result.get("series"):
        parts.append("plot=" + ",".join(quote(p, safe="") for p in result["series"]))
    return log.get_absolute_url() + ("#" + "&".join(parts) if parts else "")


def summaries(logs: list[FlightLog]) -> None:
    """Set `log.health` to {"fail": n, "warning": n, "checked": n} from each ready log's kept
    report (None without one): the list page reads files only, it never runs checks."""
    for log in logs:
        log.health = None  # type: ignore[attr-defined]
        try:
            report = json.loads(report_path(log).read_text())
        except (OSError, ValueError):
            continue
        statuses = [c.get("status") for c in report.get("checks", [])]
        log.health = {  # type: ignore[attr-defined]
            "fail": statuses.count("fail"),
            "warning": statuses.count("warning"),
            "checked": sum(s != "not_checked" for s in statuses),
        }
