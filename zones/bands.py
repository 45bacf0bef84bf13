"""Altitude bands: published limits in metres with their references, placed about home.

The ground knows a drone's height above its home only (fleet/envelopes.py): no terrain
and no home elevation. So a limit above ground level (AGL) is taken as above home, which
holds where the ground is flat around home and is said with every refusal; a limit above
mean sea level or the WGS 84 ellipsoid cannot be placed at all, and the band is widened
to be safe: such a lower limit reaches down to the ground, such an upper limit has no top.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

# The foot, 0.3048 m exactly [ICAO Annex 5].
FOOT_M = 0.3048
UNITS = {"M": 1.0, "FT": FOOT_M}
REFERENCES = ("AGL", "AMSL", "WGS84", "HOME")
# Placed about home as published.
HOME_RELATIVE = ("AGL", "HOME")


class BandError(ValueError):
    """A limit, unit or reference that cannot be read; `field` names it."""

    def __init__(self, field: str, message: str) -> None:
        super().__init__(f"{field}: {message}")
        self.field = field
        self.message = message


def to_metres(value: object, unit: object, field: str) -> float:
    """A published limit in metres; refuses unknown units and non-numbers."""
    if not isinstance(unit, str) or unit.upper() not in UNITS:
        raise BandError(field, f"unknown unit {unit!r}; expected one of M, FT")
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise BandError(field, f"must be a number, got {value!r}")
    return float(value) * UNITS[unit.upper()]


def reference(value: object, field: str) -> str:
    if not isinstance(value, str) or value.upper() not in REFERENCES:
        raise BandError(field, f"unknown vertical reference {value!r}; expected AGL, AMSL or WGS84")
    return value.upper()


@dataclass(frozen=True)
class Band:
    lower_m: float
    lower_ref: str
    upper_m: float
    upper_ref: str

    def about_home(self) -> tuple[float, float]:
        """(lowest, highest) height above home the band may cover."""
        lower = self.lower_m if self.lower_ref in HOME_RELATIVE else -math.inf
        upper = self.upper_m if self.upper_ref in HOME_RELATIVE else math.inf
        return lower, upper

    def text(self) -> str:
        """The band as published, and how it was placed: `0–60 m AGL (taken as above home:
        terrain unknown)`."""
        lower = _limit(self.lower_m, self.lower_ref)
        upper = _limit(self.upper_m, self.upper_ref)
        notes = []
        if "AGL" in (self.lower_ref, self.upper_ref):
            notes.append("AGL taken as above home: terrain unknown")
        if {self.lower_ref, self.upper_ref} - set(HOME_RELATIVE):
            notes.append("home elevation unknown: the band is widened to the ground and up")
        suffix = f" ({'; '.join(notes)})" if notes else ""
        return f"{lower} – {upper}{suffix}"


def _limit(metres: float, ref: str) -> str:
    ref_text = "above home" if ref == "HOME" else ref
    return f"{metres:g} m {ref_text}"


def checked_band(band: Band, field: str) -> Band:
    """The band, refused when its lower limit lies above its upper one (same reference)."""
    if band.lower_ref == band.upper_ref and band.lower_m > band.upper_m:
        raise BandError(field, f"lower limit {band.lower_m:g} m above upper {band.upper_m:g} m")
    return band
