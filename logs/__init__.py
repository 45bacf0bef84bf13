"""Flight-log import, columnar storage, level-of-detail and analysis.

Plain modules without Django: the upload API, the Celery import task and the viewer call
`import_log`, `store.import_to_store` / `store.open_store`, `lod.downsample`, `analysis`,
`checks.run_checks` (the health report of every imported log, docs/log-checks.md) and
`spectrum.spectrum` (Welch power spectral density of a series).
This package is also the `logs` Django app, so names load lazily: starting Django does
not import numpy, pyulog, pymavlink and rosbags.
"""

from importlib import import_module

_EXPORTS = {
    "import_log": "logs.importers",
    "Limits": "logs.importers.base",
    "LogFormatError": "logs.importers.base",
    "LogData": "logs.series",
    "Series": "logs.series",
    "find_special": "logs.series",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> object:
    if name in _EXPORTS:
        return getattr(import_module(_EXPORTS[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
