"""Flight-log import, columnar storage, level-of-detail and analysis (issue 7).

Plain modules without Django: the upload API, the Celery import task and the viewer call
`import_log`, `store.write_store` / `store.open_store`, `lod.downsample` and `analysis`.
"""

from telemetry.logs.importers import import_log
from telemetry.logs.importers.base import Limits, LogFormatError
from telemetry.logs.model import LogData, Series, find_special

__all__ = ["Limits", "LogData", "LogFormatError", "Series", "find_special", "import_log"]
