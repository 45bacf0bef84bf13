"""Where the suite's own test data lives (in the repository, beside the tests)."""

from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
TEST_DATA = ROOT / "tests" / "data"
REAL_ULOGS = TEST_DATA / "ulog"
