"""A maintenance request refused: its HTTP status, the field it names and why."""

from __future__ import annotations


class Refused(Exception):
    def __init__(self, field: str, message: str, status: int = 400) -> None:
        super().__init__(f"{field}: {message}")
        self.field = field
        self.message = message
        self.status = status
