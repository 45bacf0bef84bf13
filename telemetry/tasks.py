"""Beat task: partitions ahead, rollups of finished days, retention by dropping partitions."""

from __future__ import annotations

from datetime import UTC, datetime

from celery import shared_task
from django.conf import settings
from django.db import connection

from . import storage


@shared_task(name="telemetry.maintain_partitions")
def maintain_partitions() -> dict[str, list]:
    connection.ensure_connection()
    result = storage.maintain(
        connection.connection,
        today=datetime.now(UTC).date(),
        days_ahead=settings.TELEMETRY_PARTITIONS_AHEAD_DAYS,
        retention=storage.Retention(
            raw_days=settings.TELEMETRY_RAW_RETENTION_DAYS,
            rollup_1s_days=settings.TELEMETRY_1S_RETENTION_DAYS,
            rollup_1m_days=settings.TELEMETRY_1M_RETENTION_DAYS,
        ),
    )
    return {key: [str(v) for v in values] for key, values in result.items()}
