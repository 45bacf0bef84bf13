"""Signal receivers: what other apps do, seen from the accounts app without them
importing it (the fleet and missions apps know nothing of accounts)."""

from __future__ import annotations


def connect() -> None:
    """Called once from AppConfig.ready()."""
