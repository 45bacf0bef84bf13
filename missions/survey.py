"""Survey planning from a camera: the photogrammetry relations between sensor, lens,
height and ground resolution, and the estimates an operator checks before sending.

A nadir camera at height h with sensor width s_w, focal length f and an image w_px wide
sees a ground strip h·s_w/f wide; one pixel covers GSD = h·s_w/(f·w_px). The image's long
side lies across the flight lines, so the lines are spaced by the footprint width minus the
side overlap, and photos along a line by the footprint height minus the forward overlap.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from missions.geo import distance_m
from missions.planning import PlanningError

MIN_OVERLAP = 0.0
MAX_OVERLAP = 0.95
MIN_HEIGHT_M = 2.0
MAX_HEIGHT_M = 1000.0
# Flight-time model: climb and descent rates, and the time a multicopter loses at each
# waypoint where it stops (decelerate, settle within tolerance, accelerate).
CLIMB_M_S = 2.0
DESCENT_M_S = 1.0
STOP_OVERHEAD_S = 2.0


@dataclass(frozen=True)
class Camera:
    name: str
    sensor_width_mm: float
    sensor_height_mm: float
    focal_length_mm: float
    image_width_px: int
    image_height_px: int

    def to_dict(self) -> dict:
        return asdict(self)


# Published sensor, lens and image sizes of common survey cameras.
PRESETS: dict[str, Camera] = {
    c.name: c
    for c in (
        Camera("DJI Phantom 4 Pro", 13.2, 8.8, 8.8, 5472, 3648),
        Camera("DJI Mavic 3E", 17.3, 13.0, 12.29, 5280, 3956),
        Camera("GoPro Hero3", 6.17, 4.55, 2.77, 4000, 3000),
        Camera("Raspberry Pi Camera Module 2", 3.68, 2.76, 3.04, 3280, 2464),
        Camera("Raspberry Pi HQ Camera, 6 mm lens", 6.287, 4.712, 6.0, 4056, 3040),
        Camera("Sony RX100 III", 13.2, 8.8, 8.8, 5472, 3648),
    )
}


@dataclass(frozen=True)
class Geometry:
    """What a camera at a height gives: resolution, footprint and the two spacings."""

    height_m: float
    gsd_cm: float
    footprint_width_m: float
    footprint_height_m: float
    line_spacing_m: float
    photo_spacing_m: float

    def to_dict(self) -> dict:
        return {k: round(v, 3) for k, v in asdict(self).items()}


def camera_from(spec: Any) -> Camera:
    """A preset by name, or a camera described field by field."""
    if isinstance(spec, str):
        if spec not in PRESETS:
            raise PlanningError(
                "camera", f"unknown camera {spec!r}; choose a preset or give its sizes"
            )
        return PRESETS[spec]
    if not isinstance(spec, Mapping):
        raise PlanningError("camera", "must be a preset name or an object with the sensor sizes")
    values = {}
    for field in ("sensor_width_mm", "sensor_height_mm", "focal_length_mm"):
        values[field] = _positive(spec.get(field), f"camera.{field}")
    for field in ("image_width_px", "image_height_px"):
        values[field] = int(_positive(spec.get(field), f"camera.{field}"))
    return Camera(name=str(spec.get("name") or "Custom camera")[:100], **values)


def preset_for(gear_camera: str) -> str | None:
    """The preset a drone's gear names (its CAMERA entry), if we know it."""
    wanted = gear_camera.strip().lower()
    return next((name for name in PRESETS if name.lower() == wanted), None)


def geometry(
    camera: Camera,
    *,
    overlap: float,
    sidelap: float,
    height_m: float | None = None,
    gsd_cm: float | None = None,
) -> Geometry:
    """The flight height from a wanted ground resolution (or the resolution from a height),
    and the line and photo spacings that give the overlaps."""
    front = _fraction(overlap, "overlap")
    side = _fraction(sidelap, "sidelap")
    if (height_m is None) == (gsd_cm is None):
        raise PlanningError("height_m", "give either the flight height or the ground resolution")
    if gsd_cm is not None:
        gsd_m = _positive(gsd_cm, "gsd_cm") / 100.0
        height_m = gsd_m * camera.focal_length_mm * camera.image_width_px / camera.sensor_width_mm
    height = _positive(height_m, "height_m")
    if not MIN_HEIGHT_M <= height <= MAX_HEIGHT_M:
        raise PlanningError(
            "height_m",
            f"the flight height {height:.1f} m is outside {MIN_HEIGHT_M:g}–{MAX_HEIGHT_M:g} m",
        )
    width = height * camera.sensor_width_mm / camera.focal_length_mm
    length = height * camera.sensor_height_mm / camera.focal_length_mm
    return Geometry(
        height_m=height,
        gsd_cm=100.0 * width / camera.image_width_px,
        footprint_width_m=width,
        footprint_height_m=length,
        line_spacing_m=width * (1.0 - side),
        photo_spacing_m=length * (1.0 - front),
    )


@dataclass(frozen=True)
class Estimate:
    """One drone's share of a survey."""

    waypoints: int
    photos: int
    distance_m: float
    flight_time_s: float
    battery_pct: float | None

    def to_dict(self) -> dict:
        out = asdict(self)
        out["distance_m"] = round(self.distance_m, 1)
        out["flight_time_s"] = round(self.flight_time_s, 1)
        if self.battery_pct is not None:
            out["battery_pct"] = round(self.battery_pct, 1)
        return out


def estimate(
    waypoints: Sequence[Sequence[float]],
    *,
    home: Sequence[float],
    height_m: float,
    speed_m_s: float,
    photos_per_waypoint: int = 1,
    endurance_s: float | None = None,
) -> Estimate:
    """Distance and time of take-off at home, the legs through every waypoint, the way
    back and the landing; battery as the share of the drone's endurance it uses."""
    speed = _positive(speed_m_s, "speed_m_s")
    route = np.array([home[:2], *(p[:2] for p in waypoints), home[:2]], dtype=float)
    distance = float(distance_m(route[:-1, 0], route[:-1, 1], route[1:, 0], route[1:, 1]).sum())
    seconds = (
        distance / speed
        + len(waypoints) * STOP_OVERHEAD_S
        + height_m / CLIMB_M_S
        + height_m / DESCENT_M_S
    )
    battery = None if not endurance_s else 100.0 * seconds / endurance_s
    return Estimate(
        waypoints=len(waypoints),
        photos=len(waypoints) * photos_per_waypoint,
        distance_m=distance,
        flight_time_s=seconds,
        battery_pct=battery,
    )


def _positive(value: Any, field: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise PlanningError(field, "must be a number")
    if value <= 0:
        raise PlanningError(field, "must be greater than 0")
    return float(value)


def _fraction(value: Any, field: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise PlanningError(field, "must be a fraction between 0 and 0.95")
    if not MIN_OVERLAP <= value <= MAX_OVERLAP:
        raise PlanningError(field, f"must be between {MIN_OVERLAP:g} and {MAX_OVERLAP:g}")
    return float(value)
