"""Units: what each format says (or, for PX4 ULog, what its field names say) and how the
portal shows it: SI-style display units (m, m/s, °, %, V, A) and the factor from stored
values to displayed ones. Stored series keep the recorder's numbers and unit; the API
converts at the edge (series, values, summaries), so analyses read what was recorded."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass


@dataclass(frozen=True)
class Display:
    unit: str  # shown to the user
    factor: float = 1.0  # displayed value = stored value * factor

    @property
    def converts(self) -> bool:
        return self.factor != 1.0


DEG = "°"
RAD_TO_DEG = 180.0 / math.pi

# Recorded unit (lower case) -> display unit and factor. Units not listed show as recorded.
CONVERSIONS: dict[str, Display] = {
    "mm": Display("m", 1e-3),
    "cm": Display("m", 1e-2),
    "km": Display("m", 1e3),
    "mm/s": Display("m/s", 1e-3),
    "cm/s": Display("m/s", 1e-2),
    "km/h": Display("m/s", 1 / 3.6),
    "m/s/s": Display("m/s²", 1.0),
    "m/s2": Display("m/s²", 1.0),
    "m/s^2": Display("m/s²", 1.0),
    "mg": Display("m/s²", 9.80665e-3),
    "rad": Display(DEG, RAD_TO_DEG),
    "rad/s": Display(f"{DEG}/s", RAD_TO_DEG),
    "rad/s/s": Display(f"{DEG}/s²", RAD_TO_DEG),
    "mrad": Display(DEG, RAD_TO_DEG / 1000),
    "deg": Display(DEG),
    "degree": Display(DEG),
    "degrees": Display(DEG),
    "cdeg": Display(DEG, 1e-2),
    "centidegrees": Display(DEG, 1e-2),
    "degheading": Display(DEG),
    "deglatitude": Display(DEG),
    "deglongitude": Display(DEG),
    "dege7": Display(DEG, 1e-7),
    "deg/s": Display(f"{DEG}/s"),
    "degc": Display("°C"),
    "celsius": Display("°C"),
    "cdegc": Display("°C", 1e-2),
    "mv": Display("V", 1e-3),
    "cv": Display("V", 1e-2),
    "ma": Display("A", 1e-3),
    "ca": Display("A", 1e-2),
    "fraction": Display("%", 100.0),
    "norm": Display("%", 100.0),
    "percent": Display("%"),
    "hpa": Display("Pa", 100.0),
    "mbar": Display("Pa", 100.0),
    "ms": Display("s", 1e-3),
    "us": Display("s", 1e-6),
    "µs": Display("µs"),  # PWM pulse widths stay in microseconds
}


def display(unit: str) -> Display:
    """How a recorded unit is shown: converted (mm -> m, rad -> °, fraction -> %) or as is."""
    return CONVERSIONS.get(unit.strip().lower(), Display(unit))


# PX4 ULog formats carry no units; PX4's uORB field names and message definitions do.
# (topic pattern, field pattern) -> recorded unit, first match wins; fields are matched
# without their array index ("gyro_rad[0]" -> "gyro_rad").
ULOG_FIELDS: list[tuple[str, str, str]] = [
    (r"vehicle_gps_position|sensor_gps", r"lat|lon", "degE7"),
    (r"vehicle_gps_position|sensor_gps", r"alt|alt_ellipsoid", "mm"),
    (r"vehicle_gps_position|sensor_gps", r"eph|epv", "m"),
    (r"vehicle_global_position|home_position", r"lat|lon", "deg"),
    (r"vehicle_global_position|home_position", r"alt|alt_ellipsoid|terrain_alt", "m"),
    (r"vehicle_local_position.*", r"x|y|z|dist_bottom|eph|epv|ref_alt|hagl_min|hagl_max", "m"),
    (r"vehicle_local_position.*", r"vx|vy|vz|vxy_max|vz_max|evh|evv", "m/s"),
    (r"vehicle_local_position.*", r"ax|ay|az", "m/s/s"),
    (r"vehicle_local_position.*", r"heading|delta_heading", "rad"),
    (r"vehicle_local_position.*", r"ref_lat|ref_lon", "deg"),
    (r"battery_status", r"remaining", "fraction"),
    (r"battery_status", r"temperature", "degC"),
    (r"sensor_(accel|gyro|mag|baro)|differential_pressure", r"temperature", "degC"),
    (r"sensor_accel", r"x|y|z", "m/s/s"),
    (r"sensor_gyro", r"x|y|z", "rad/s"),
    (r"sensor_baro", r"pressure", "hPa"),
    (r"vehicle_angular_velocity", r"xyz", "rad/s"),
    (r"vehicle_attitude_setpoint", r"roll_body|pitch_body|yaw_body", "rad"),
    (r"vehicle_rates_setpoint", r"roll|pitch|yaw", "rad/s"),
    (r"cpuload", r"load|ram_usage", "fraction"),
    (r"input_rc", r"values", "µs"),
    (r"actuator_outputs", r"output", "µs"),
]
# Field-name suffixes PX4 uses for units; checked after the table.
ULOG_SUFFIXES: list[tuple[str, str]] = [
    ("_m_s2", "m/s/s"), ("_m_s_s", "m/s/s"), ("_m_s", "m/s"), ("_rad_s", "rad/s"),
    ("_meter", "m"), ("_m", "m"), ("_rad", "rad"), ("_deg", "deg"), ("_mah", "mAh"),
    ("_v", "V"), ("_a", "A"), ("_pa", "Pa"), ("_hz", "Hz"), ("_celsius", "degC"),
    ("_celcius", "degC"), ("_ga", "Ga"), ("_ms", "ms"), ("_us", "us"), ("_kb_s", "kB/s"),
]  # fmt: skip
_INDEX = re.compile(r"\[\d+\]")


def ulog_unit(topic: str, field: str) -> str:
    """The recorded unit of a PX4 uORB field, from its topic and name ("" when unknown)."""
    name = _INDEX.sub("", field.rsplit(".", 1)[-1])
    for topic_pattern, field_pattern, unit in ULOG_FIELDS:
        if re.fullmatch(topic_pattern, topic) and re.fullmatch(field_pattern, name):
            return unit
    if name in ("timestamp", "timestamp_sample") or name.endswith("_timestamp"):
        return "us"
    for suffix, unit in ULOG_SUFFIXES:
        if name.endswith(suffix) and name != suffix.lstrip("_"):
            return unit
    return ""
