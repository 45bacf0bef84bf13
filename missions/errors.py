"""The error every mission decision raises for a request the domain refuses."""

from __future__ import annotations

from fleet import envelopes


class MissionError(ValueError):
    """A request the domain refuses; `field` names the input, `status` the HTTP answer."""

    def __init__(
        self,
        field: str,
        message: str,
        status: int = 400,
        code: str | None = None,
        reasons: list[str] | None = None,
    ) -> None:
        super().__init__(f"{field}: {message}")
        self.field = field
        self.message = message
        self.status = status
        self.code = code
        # Each reason a `not_airworthy` refusal names, answered as the body's `reasons`.
        self.reasons = reasons


def outside_envelope(exc: envelopes.EnvelopeRefusal) -> MissionError:
    """The 409 for a mission step the envelope refuses, or that goes beyond its defaults
    unconfirmed (nothing is sent)."""
    return MissionError("steps", exc.message, 409, exc.code)
