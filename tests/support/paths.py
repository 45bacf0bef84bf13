"""Where the project's shared documents and test data live: `../shared` beside the clone."""

import os
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SHARED = Path(os.environ.get("SKYHIVE_SHARED", ROOT.parent / "shared"))
REAL_ULOGS = SHARED / "testdata" / "ulog"
