"""An import function that kills the worker process running it, for the redelivery tests.

Selected in a worker's environment with LOGS_IMPORT_FUNCTION (config/settings/logs.py):
it parses nothing, waits CRASH_AFTER_S seconds (the import looks busy) and then ends the
process at once, as a segfault in a parser or the kernel's OOM killer would.
"""

from __future__ import annotations

import os
import time
from pathlib import Path


def import_to_store(path: Path, directory: Path, **_: object) -> None:
    time.sleep(float(os.environ.get("CRASH_AFTER_S", "1")))
    os._exit(70)
