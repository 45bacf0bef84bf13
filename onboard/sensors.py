"""A simulated gas/weather sensor: CO2, temperature and humidity as fields over an area.

The field is a baseline plus "plumes": circular areas where a quantity rises towards a
peak at the centre (linear fall-off to the rim). A test or demo places a CO2 plume with a
JSON file or CLI option, so a drone sensing over it reads high values and the fail-safe
raises OUT_MEASURE there.

JSON form (a list, or {"plumes": [...], "baseline": {...}}):
  {"baseline": {"CO2": 415},
   "plumes": [{"sensor": "CO2", "lat": 40.63, "lon": -8.65, "radius_m": 30, "peak": 2000}]}
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .navigation import EARTH_RADIUS

UNITS = {"CO2": "ppm", "TEMPERATURE": "degC", "HUMIDITY": "%"}
BASELINE = {"CO2": 415.0, "TEMPERATURE": 20.0, "HUMIDITY": 50.0}
# Sensor names in the gear list that this simulated sensor answers, by quantity.
ALIASES = {
    "CO2": "CO2",
    "TEMPERATURE": "TEMPERATURE",
    "TEMP": "TEMPERATURE",
    "HUMIDITY": "HUMIDITY",
    "RH": "HUMIDITY",
}


class SensorConfigError(ValueError):
    pass


@dataclass(frozen=True)
class Plume:
    sensor: str
    lat: float
    lon: float
    radius_m: float
    peak: float

    def value(self, lat: float, lon: float, base: float) -> float:
        d = ground_distance(lat, lon, self.lat, self.lon)
        if d >= self.radius_m:
            return base
        return base + (self.peak - base) * (1.0 - d / self.radius_m)


def ground_distance(lat1: float, lon1: float, lat2: float, lon2: float) -> float:
    """Metres between two nearby points (equirectangular; plumes are small)."""
    mean_lat = math.radians((lat1 + lat2) / 2)
    dn = math.radians(lat2 - lat1) * EARTH_RADIUS
    de = math.radians(lon2 - lon1) * EARTH_RADIUS * math.cos(mean_lat)
    return math.hypot(dn, de)


@dataclass
class SensorField:
    baseline: dict[str, float] = field(default_factory=lambda: dict(BASELINE))
    plumes: list[Plume] = field(default_factory=list)

    def quantity(self, sensor: str) -> str:
        quantity = ALIASES.get(sensor.upper())
        if quantity is None:
            raise KeyError(f"The simulated sensor does not measure {sensor}.")
        return quantity

    def value(self, sensor: str, lat: float | None, lon: float | None) -> float:
        quantity = self.quantity(sensor)
        base = self.baseline.get(quantity, BASELINE[quantity])
        if lat is None or lon is None:
            return base
        value = base
        for plume in self.plumes:
            if plume.sensor == quantity:
                value = max(value, plume.value(lat, lon, base))
        return value

    def read(self, sensor: str, lat: float | None, lon: float | None, alt: float | None) -> dict:
        quantity = self.quantity(sensor)
        return {
            "sensor": sensor,
            "value": round(self.value(sensor, lat, lon), 3),
            "unit": UNITS[quantity],
            "ts": time.time(),
            "position": None if lat is None else {"lat": lat, "lon": lon, "alt": alt or 0.0},
        }


def parse_plume(obj: Any, name: str = "plume") -> Plume:
    if not isinstance(obj, dict):
        raise SensorConfigError(f"{name} must be an object")
    try:
        sensor = ALIASES[str(obj.get("sensor", "CO2")).upper()]
        plume = Plume(
            sensor, float(obj["lat"]), float(obj["lon"]), float(obj["radius_m"]), float(obj["peak"])
        )
    except KeyError as exc:
        raise SensorConfigError(f"{name} needs {exc}") from None
    except (TypeError, ValueError) as exc:
        raise SensorConfigError(f"{name}: {exc}") from None
    if not (-90 <= plume.lat <= 90 and -180 <= plume.lon <= 180) or plume.radius_m <= 0:
        raise SensorConfigError(f"{name}: lat/lon out of range or radius not positive")
    return plume


def parse_plume_option(text: str) -> Plume:
    """CLI form `LAT,LON,RADIUS_M,PEAK[,SENSOR]`."""
    parts = text.split(",")
    if len(parts) not in (4, 5):
        raise SensorConfigError("a plume is LAT,LON,RADIUS_M,PEAK[,SENSOR]")
    keys = ("lat", "lon", "radius_m", "peak", "sensor")
    return parse_plume(dict(zip(keys, parts, strict=False)))


def load_field(path: str | Path) -> SensorField:
    data = json.loads(Path(path).read_text())
    if isinstance(data, list):
        data = {"plumes": data}
    if not isinstance(data, dict):
        raise SensorConfigError("the sensor field must be a list of plumes or an object")
    baseline = dict(BASELINE)
    for key, value in (data.get("baseline") or {}).items():
        baseline[ALIASES.get(key.upper(), key.upper())] = float(value)
    plumes = [parse_plume(p, f"plumes[{i}]") for i, p in enumerate(data.get("plumes") or [])]
    return SensorField(baseline, plumes)
