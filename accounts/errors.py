"""The one error the accounts modules raise for a refused change."""

from __future__ import annotations


class Refused(ValueError):
    """A change refused: `message` says why, `status` is the HTTP status, `field` the
    input at fault (if one is)."""

    def __init__(self, message: str, status: int = 400, field: str | None = None) -> None:
        super().__init__(message)
        self.message = message
        self.status = status
        self.field = field
