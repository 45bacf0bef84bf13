"""Altitude bands: published limits in metres with their references, placed about home.

The ground knows a drone's height above its home. A limit above mean sea level (AMSL) is
placed with the home's elevation when imported terrain gives it (terrain/); without it,
and for a limit above the WGS 84 ellipsoid (which needs the geoid too), the limit cannot
be placed and the band is widened to be safe: such a lower limit reaches down to the
ground, such an upper limit has no top. A limit above ground level (AGL) is taken as
above home, which holds where the ground around home is flat: the variation of the
terrain across a zone is not used. Every refusal says how its band was placed.
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

    def about_home(self, home_elevation: float | None = None) -> tuple[float, float]:
        """(lowest, highest) height above home the band may cover, the home being
        `home_elevation` m above mean sea level (None: unknown)."""
        return (
            _placed(self.lower_m, self.lower_ref, home_elevation, -math.inf),
            _placed(self.upper_m, self.upper_ref, home_elevation, math.inf),
        )

    def text(self, home_elevation: float | None = None) -> str:
        """The band as published, and how it was placed: `0 m AGL – 60 m AGL (AGL taken
        as above home: terrain unknown)`."""
        lower = _limit(self.lower_m, self.lower_ref)
        upper = _limit(self.upper_m, self.upper_ref)
        refs = {self.lower_ref, self.upper_ref}
        notes = []
        if "AGL" in refs:
            known = "terrain unknown" if home_elevation is None else "the zone's terrain unused"
            notes.append(f"AGL taken as above home: {known}")
        if "AMSL" in refs and home_elevation is not None:
            notes.append(f"AMSL placed with home at {home_elevation:.0f} m AMSL")
        if "WGS84" in refs or ("AMSL" in refs and home_elevation is None):
            notes.append("home elevation unknown: the band is widened to the ground and up")
        suffix = f" ({'; '.join(notes)})" if notes else ""
        return f"{lower} – {upper}{suffix}"


def _placed(metres: float, ref: str, home_elevation: float | None, unknown: float) -> float:
    if ref in HOME_RELATIVE:
        return metres
    if ref == "AMSL" and home_elevation is not None:
        return metres - home_elevation
    return unknown


def _limit(metres: float, ref: str) -> str:
    ref_text = "above home" if ref == "HOME" else ref
    return f"{metres:g} m {ref_text}"


def checked_band(band: Band, field: str) -> Band:
    """The band, refused when its lower limit lies above its upper one (same reference)."""
    if band.lower_ref == band.upper_ref and band.lower_m > band.upper_m:
        raise BandError(field, f"lower limit {band.lower_m:g} m above upper {band.upper_m:g} m")
    return band
