"""QGroundControl `.plan` files (JSON, fileType "Plan", version 1) ↔ our mission steps.

Mission items map onto mission steps (docs/protocol.md), altitudes relative to home. A
survey or corridor scan is flattened into the simple items QGroundControl generated for
it and saved inside it (TransectStyleComplexItem.Items); a complex item without them is
refused. It re-exports as those simple items.

| item | steps |
|---|---|
| 22 NAV_TAKEOFF, 84 NAV_VTOL_TAKEOFF | arm, takeoff(altitude), wait_for_flight — QGC missions start disarmed on the ground; the autopilot completes the climb before the next item |
| 16 NAV_WAYPOINT | navigate(lat, lon, altitude_delta), wait_for_flight(acceptance radius), sleep(hold) if hold > 0 |
| the first altitude of a plan with no take-off | arm, takeoff(that altitude), wait_for_flight before its item, as PX4 climbs to the first waypoint's altitude when a mission needs no take-off item (`MIS_TAKEOFF_REQ`); under 0.5 m is refused |
| 19 NAV_LOITER_TIME | navigate, wait_for_flight, sleep(time) |
| 21 NAV_LAND, 85 NAV_VTOL_LAND | land, preceded by navigate + wait_for_flight when it is not where the drone already is |
| 20 NAV_RETURN_TO_LAUNCH | navigate(home), wait_for_flight, land |
| 178 DO_CHANGE_SPEED | `speed` on every following navigate (a speed of -1 or 0 keeps the current one); a climb or descent speed is refused |
| 201 DO_SET_ROI (mode location), 195 DO_SET_ROI_LOCATION | `roi` [lat, lon] on every following navigate |
| 197 DO_SET_ROI_NONE, 201 with mode none | following navigates carry no `roi` |
| 201 DO_SET_ROI in an ArduPilot plan (firmwareType 3) | `roi` at params 5-6 whatever param 1, none when lat, lon and alt are all 0: ArduPilot reads it so, and QGroundControl leaves its param 1 at 0 |
| 206 DO_SET_CAM_TRIGG_DIST | `photo_distance` on every following wait_for_flight (0 stops); "trigger once" is a takepic |
| 2000 IMAGE_START_CAPTURE, 203 DO_DIGICAM_CONTROL | takepic |

Altitudes: relative (frame 3, AltitudeMode 1) as they are; AMSL (frame 0, AltitudeMode 2)
minus plannedHomePosition's altitude; above terrain (AltitudeMode 3 "calculated above
terrain", or frame 10 MAV_FRAME_GLOBAL_TERRAIN_ALT / AltitudeMode 4 "terrain frame"): with
imported terrain covering the item and home, the terrain's elevation at the item plus the
height above it, minus the terrain's elevation at home (home is on the ground); without,
the item's AMSLAltAboveTerrain (QGroundControl's own calculation) minus home's altitude,
and an item with neither is refused.

Where the step list cannot tell two items apart (a hold waypoint from a loiter, RTL from
a land at home, the two camera commands) or has no place for a value (takeoff
coordinate, pass radius, yaw), the first step of the item carries `params["qgc"]`: the
command, its non-derived params and frame. The onboard agent ignores unknown params
(onboard.protocol.validate_command drops them), so these hints never change a flight;
they let a plan made in QGroundControl import and re-export with equal mission items.
Steps without hints (our own missions) export canonically. The geofence and the rally
points have no step form: they come back as plain dicts to store beside the mission.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from missions.planning import PlanningError
from onboard.envelope import (
    Circle,
    Envelope,
    EnvelopeError,
    Polygon,
    geofence_dict,
    parse_geofence,
)
from onboard.protocol import ProtocolError, validate_command

# The largest .plan read: the ceiling the import endpoint applies before reading (a plan
# of thousands of items is a few hundred KB), so json.loads works on a bounded text.
MAX_PLAN_BYTES = 8 * 1024 * 1024

NAV_WAYPOINT = 16
NAV_LOITER_TIME = 19
NAV_RETURN_TO_LAUNCH = 20
NAV_LAND = 21
NAV_TAKEOFF = 22
NAV_VTOL_TAKEOFF = 84
NAV_VTOL_LAND = 85
DO_CHANGE_SPEED = 178
DO_SET_ROI_LOCATION = 195
DO_SET_ROI_NONE = 197
DO_SET_ROI = 201
DO_DIGICAM_CONTROL = 203
DO_SET_CAM_TRIGG_DIST = 206
IMAGE_START_CAPTURE = 2000
MAV_ROI_NONE = 0
MAV_ROI_LOCATION = 3
# DO_CHANGE_SPEED param 1, the speed type: 0 airspeed, 1 ground speed (horizontal), 2 climb,
# 3 descent (MAVLink common.xml).
HORIZONTAL_SPEED_TYPES = (0, 1)
# MAV_AUTOPILOT_ARDUPILOTMEGA, the plan's mission.firmwareType for ArduPilot.
FIRMWARE_ARDUPILOT = 3

FRAME_GLOBAL = 0  # altitude above mean sea level
FRAME_MISSION = 2  # the item has no coordinate
FRAME_GLOBAL_RELATIVE_ALT = 3
FRAME_GLOBAL_TERRAIN_ALT = 10
# QGroundControl's AltitudeFrame (QGroundControlQmlGlobal): what an item's Altitude means.
ALTITUDE_MODE_RELATIVE = 1
ALTITUDE_MODE_ABSOLUTE = 2
ALTITUDE_MODE_CALC_ABOVE_TERRAIN = 3
ALTITUDE_MODE_TERRAIN = 4
TERRAIN_MODES = (ALTITUDE_MODE_CALC_ABOVE_TERRAIN, ALTITUDE_MODE_TERRAIN)

TAKEOFF_COMMANDS = (NAV_TAKEOFF, NAV_VTOL_TAKEOFF)
LAND_COMMANDS = (NAV_LAND, NAV_VTOL_LAND)
COORDINATE_COMMANDS = (NAV_WAYPOINT, NAV_LOITER_TIME) + LAND_COMMANDS + TAKEOFF_COMMANDS
CAMERA_COMMANDS = (IMAGE_START_CAPTURE, DO_DIGICAM_CONTROL)
# Items that change how the following legs are flown, not where.
SETTING_COMMANDS = (
    DO_CHANGE_SPEED,
    DO_SET_ROI,
    DO_SET_ROI_LOCATION,
    DO_SET_ROI_NONE,
    DO_SET_CAM_TRIGG_DIST,
)
SUPPORTED_COMMANDS = (
    COORDINATE_COMMANDS + (NAV_RETURN_TO_LAUNCH,) + CAMERA_COMMANDS + SETTING_COMMANDS
)

# params 1-4 as QGroundControl writes them for a new item (yaw NaN is written as null).
_DEFAULT_P = {
    NAV_WAYPOINT: [0, 0, 0, None],
    NAV_LOITER_TIME: [0, 0, 0, None],
    NAV_LAND: [0, 0, 0, None],
    NAV_TAKEOFF: [0, 0, 0, None],
    NAV_VTOL_TAKEOFF: [0, 0, 0, None],
    NAV_VTOL_LAND: [0, 0, 0, None],
}
# Camera items have no coordinate: all seven params are theirs (CameraSection "Take photo").
_DEFAULT_CAMERA = {
    IMAGE_START_CAPTURE: [0, 0, 1, 0, None, None, None],
    DO_DIGICAM_CONTROL: [0, 0, 0, 0, 1, 0, 0],
}
DEFAULT_ALTITUDE = 10.0
# The terrain's elevation above mean sea level at (lat, lon), None where it is unknown.
Terrain = Callable[[float, float], float | None]


class QgcPlanError(PlanningError):
    """A .plan file we cannot read or a step list we cannot write; `field` locates it."""


@dataclass(frozen=True)
class QgcPlan:
    steps: list[dict]
    home: list[float] | None = None  # [lat, lon, AMSL altitude]
    geofence: dict = field(default_factory=lambda: {"polygons": [], "circles": []})
    rally_points: list[list[float]] = field(default_factory=list)  # [[lat, lon, alt]]
    cruise_speed: float | None = None
    hover_speed: float | None = None
    firmware_type: int = 12  # MAV_AUTOPILOT_PX4, QGroundControl's default
    vehicle_type: int = 2  # MAV_TYPE_QUADROTOR

    def to_dict(self) -> dict:
        return {
            "steps": self.steps,
            "home": self.home,
            "geofence": self.geofence,
            "rally_points": self.rally_points,
            "cruise_speed": self.cruise_speed,
            "hover_speed": self.hover_speed,
            "firmware_type": self.firmware_type,
            "vehicle_type": self.vehicle_type,
        }


def _command_name(command: int) -> str:
    try:
        from pymavlink.dialects.v20 import common

        return common.enums["MAV_CMD"][command].name
    except (ImportError, KeyError):
        return f"MAV_CMD {command}"


# ---------------------------------------------------------------------------------------
# Reading.


def _num(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise QgcPlanError(where, f"must be a number, got {value!r}")
    return value


def _optional(value: Any, where: str) -> float | None:
    """QGroundControl writes NaN (an unset param) as null."""
    return None if value is None else _num(value, where)


def _obj(value: Any, where: str) -> Mapping:
    if not isinstance(value, Mapping):
        raise QgcPlanError(where, "must be a JSON object")
    return value


def _list(value: Any, where: str) -> list:
    if not isinstance(value, list):
        raise QgcPlanError(where, "must be a list")
    return value


def _latlon(lat: Any, lon: Any, where: str) -> tuple[float, float]:
    lat = _num(lat, f"{where}.lat")
    lon = _num(lon, f"{where}.lon")
    if not (-90 <= lat <= 90 and -180 <= lon <= 180):
        raise QgcPlanError(where, f"({lat}, {lon}) is not a WGS84 coordinate")
    return lat, lon


class _Reader:
    """Turns mission items into steps, tracking the altitude, where the drone is and the
    settings (speed, region of interest, camera trigger distance) of the legs to come."""

    def __init__(
        self, home: list[float] | None, terrain: Terrain | None = None, firmware: int = 12
    ) -> None:
        self.home = home
        self.terrain = terrain
        self.firmware = firmware
        self.altitude: float | None = None
        self.position: tuple[float, float] | None = None
        self.armed = False
        self.speed: float | None = None
        self.roi: list[float] | None = None
        self.photo_distance: float | None = None
        self.body: list[tuple[str, dict]] = []
        self.sources: list[str] = []  # the item each step came from, for error messages
        self.where = ""

    def add(self, command: str, params: dict) -> None:
        if command == "wait_for_flight" and self.photo_distance:
            params = {**params, "photo_distance": self.photo_distance}
        self.body.append((command, params))
        self.sources.append(self.where)

    def amsl_to_relative(self, amsl: float, where: str) -> float:
        if self.home is None:
            raise QgcPlanError(where, "an AMSL altitude needs plannedHomePosition")
        return amsl - self.home[2]

    def relative_altitude(
        self, item: Mapping, alt: float | None, where: str, point: tuple[float, float] | None
    ) -> float:
        """The item's altitude above home, whatever frame QGroundControl wrote it in;
        `point` is where the item is (None: over home)."""
        frame, mode = item.get("frame"), item.get("AltitudeMode")
        if mode in TERRAIN_MODES or frame == FRAME_GLOBAL_TERRAIN_ALT:
            return self.above_terrain(item, alt, where, point)
        if alt is None:
            raise QgcPlanError(f"{where}.params[6]", "the altitude is missing")
        if frame == FRAME_GLOBAL_RELATIVE_ALT:
            return alt
        if frame == FRAME_GLOBAL:
            return self.amsl_to_relative(alt, where)
        raise QgcPlanError(where, f"frame {frame!r} is not supported (use relative altitude)")

    def above_terrain(
        self, item: Mapping, alt: float | None, where: str, point: tuple[float, float] | None
    ) -> float:
        """A height above the terrain → above home: by the imported terrain, else by the
        AMSL altitude QGroundControl calculated for the item."""
        height = item.get("Altitude") if item.get("AltitudeMode") in TERRAIN_MODES else alt
        if item.get("frame") == FRAME_GLOBAL_TERRAIN_ALT and alt is not None:
            height = alt  # MAV_FRAME_GLOBAL_TERRAIN_ALT: param 7 is above terrain
        height = None if height is None else _num(height, f"{where}.Altitude")
        over = point or (tuple(self.home[:2]) if self.home else None)
        ground = self.ground_between(over) if height is not None else None
        if ground is not None:
            return height + ground  # type: ignore[operator]
        amsl = item.get("AMSLAltAboveTerrain")
        if amsl is None:
            raise QgcPlanError(
                where,
                "its altitude is above terrain, no imported terrain covers it and home, and "
                "the plan holds no AMSL altitude for it (AMSLAltAboveTerrain) — import the "
                "terrain (manage.py import_terrain), save the plan again in QGroundControl "
                "with its terrain data loaded (it then writes AMSLAltAboveTerrain), or use "
                "relative altitudes",
            )
        return self.amsl_to_relative(_num(amsl, f"{where}.AMSLAltAboveTerrain"), where)

    def ground_between(self, point: tuple[float, float] | None) -> float | None:
        """How much higher the terrain is at `point` than at home, or None when unknown."""
        if self.terrain is None or self.home is None or point is None:
            return None
        here, home = self.terrain(*point), self.terrain(self.home[0], self.home[1])
        return None if here is None or home is None else here - home

    def navigate(self, lat: float, lon: float, alt: float | None, hint: dict | None) -> None:
        params: dict = {"lat": lat, "lon": lon}
        if alt is not None and self.altitude is None:
            self.climb_to_first(alt)
        if alt is not None:
            if self.altitude is not None and alt != self.altitude:
                params["altitude_delta"] = alt - self.altitude
            self.altitude = alt
        if self.speed is not None:
            params["speed"] = self.speed
        if self.roi is not None:
            params["roi"] = list(self.roi)
        if hint:
            params["qgc"] = hint
        self.add("navigate", params)
        self.position = (lat, lon)

    def climb_to_first(self, alt: float) -> None:
        """A plan with no take-off gives its first altitude above home, not a change from
        where the drone is: arm and climb to it first, as PX4 does when a mission starts
        with a waypoint (`MIS_TAKEOFF_REQ` 0, "Mission Mode (Multicopter)", docs.px4.io)."""
        if alt < 0.5:
            raise QgcPlanError(
                f"{self.where}.params[6]",
                f"the plan has no take-off, so it starts with a climb to its first altitude, "
                f"{alt:g} m above home, which must be at least 0.5 m; add a take-off in "
                "QGroundControl (a rover's or a submarine's plan is not for an aircraft)",
            )
        # Marked, so that the plan exports again without a take-off item of its own.
        self.takeoff(list(_DEFAULT_P[NAV_TAKEOFF]), {"implied": True}, None, alt, self.where)

    def complex_item(self, item: Mapping, where: str, number: int | None) -> None:
        """A survey or corridor scan: QGroundControl saves the items it generated; fly those."""
        transect = item.get("TransectStyleComplexItem")
        inner = transect.get("Items") if isinstance(transect, Mapping) else None
        if not isinstance(inner, list):
            raise QgcPlanError(
                where,
                f"complex item {item.get('complexItemType')!r} holds no generated items "
                "(TransectStyleComplexItem.Items) to fly; convert it to waypoints in "
                "QGroundControl first",
            )
        for j, raw in enumerate(inner):
            inner_where = f"{where}.TransectStyleComplexItem.Items[{j}]"
            inner_item = _obj(raw, inner_where)
            # QGroundControl generates simple items only; nesting would also make the
            # reading recurse as deep as the file wants.
            if inner_item.get("type") == "ComplexItem":
                raise QgcPlanError(inner_where, "a complex item inside a complex item")
            self.item(inner_item, inner_where, number)

    def item(self, item: Mapping, where: str, number: int | None) -> None:
        """One mission item (`number`: its 1-based place in the plan) as Skyhive steps."""
        self.where = where
        kind = item.get("type")
        if kind == "ComplexItem":
            self.complex_item(item, where, number)
            return
        if kind != "SimpleItem":
            raise QgcPlanError(where, f"unknown item type {kind!r}")
        command = item.get("command")
        p, hint = self.simple_params(item, command, where, number)
        if command in SETTING_COMMANDS:
            self.setting(command, p, where)
        elif command in CAMERA_COMMANDS:
            if p != _DEFAULT_CAMERA[IMAGE_START_CAPTURE] or command != IMAGE_START_CAPTURE:
                hint["p"] = p
            self.add("takepic", {"qgc": hint} if len(hint) > 1 else {})
        elif command == NAV_RETURN_TO_LAUNCH:
            self.return_to_launch(p, hint, where)
        else:
            self.coordinate_item(item, command, p, hint, where)

    def coordinate_item(self, item: Mapping, command: int, p: list, hint: dict, where: str) -> None:
        coordinate = None if p[4] is None and p[5] is None else _latlon(p[4], p[5], where)
        alt = self.relative_altitude(item, p[6], where, coordinate)
        if command in TAKEOFF_COMMANDS:
            self.takeoff(p, hint, coordinate, alt, where)
            return
        if coordinate is None:
            raise QgcPlanError(where, "needs a latitude and longitude")
        if command in LAND_COMMANDS:
            self.land(p, hint, coordinate, alt)
            return
        self.waypoint(command, p, hint, coordinate, alt, where)

    def setting(self, command: int, p: list, where: str) -> None:
        """Speed, region of interest and distance camera: they apply to the legs after."""
        if command == DO_CHANGE_SPEED:
            if p[0] is not None and p[0] not in HORIZONTAL_SPEED_TYPES:
                raise QgcPlanError(
                    f"{where}.params[0]",
                    f"speed type {p[0]:g} (a climb or descent speed) is not supported; only "
                    "an airspeed or ground speed (0 or 1)",
                )
            speed = p[1]
            if speed is not None and speed > 0:
                self.speed = speed
        elif command == DO_SET_ROI and self.firmware == FIRMWARE_ARDUPILOT:
            # ArduPilot ignores param 1 and clears the region of interest only when the
            # location is all zero ("MAV_CMD_DO_SET_ROI", ArduPilot Copter documentation).
            located = any(v not in (None, 0) for v in p[4:7])
            self.roi = list(_latlon(p[4], p[5], where)) if located else None
        elif command == DO_SET_ROI_NONE or (command == DO_SET_ROI and p[0] == MAV_ROI_NONE):
            self.roi = None
        elif command == DO_SET_ROI and p[0] != MAV_ROI_LOCATION:
            raise QgcPlanError(
                where, f"region of interest mode {p[0]!r} is not supported (only a location)"
            )
        elif command in (DO_SET_ROI, DO_SET_ROI_LOCATION):
            self.roi = list(_latlon(p[4], p[5], where))
        else:  # DO_SET_CAM_TRIGG_DIST
            distance = p[0] or 0
            if distance < 0:
                raise QgcPlanError(
                    f"{where}.params[0]", "the trigger distance must not be negative"
                )
            self.photo_distance = distance or None
            if p[2] == 1:
                self.add("takepic", {})

    def simple_params(
        self, item: Mapping, command: Any, where: str, number: int | None
    ) -> tuple[list, dict]:
        """A supported command's seven params and the hint of what differs from defaults."""
        if command not in SUPPORTED_COMMANDS:
            place = f"item {number}" if number is not None else "an item"
            name = _command_name(command) if isinstance(command, int) else repr(command)
            raise QgcPlanError(
                where,
                f"{place} ({name}, command {command!r}, doJumpId {item.get('doJumpId')}) is "
                "not supported; remove it or replace it in QGroundControl",
            )
        params = _list(item.get("params"), f"{where}.params")
        if len(params) != 7:
            raise QgcPlanError(f"{where}.params", "must hold 7 values")
        p = [_optional(v, f"{where}.params[{i}]") for i, v in enumerate(params)]
        hint: dict = {"command": command}
        if item.get("autoContinue", True) is not True:
            hint["autoContinue"] = item.get("autoContinue")
        if command not in COORDINATE_COMMANDS and item.get("frame") != FRAME_MISSION:
            hint["frame"] = item.get("frame")
        return p, hint

    def return_to_launch(self, p: list, hint: dict, where: str) -> None:
        if self.home is None:
            raise QgcPlanError(where, "return to launch needs plannedHomePosition")
        if p != [0] * 7:
            hint["p"] = p
        self.navigate(self.home[0], self.home[1], None, hint)
        self.add("wait_for_flight", {})
        self.add("land", {})

    def takeoff(
        self,
        p: list,
        hint: dict,
        coordinate: tuple[float, float] | None,
        alt: float,
        where: str,
    ) -> None:
        """Take off (arming first, once); a take-off spot off home is kept as a hint."""
        if alt < 0.5:
            raise QgcPlanError(f"{where}.params[6]", "takeoff altitude must be at least 0.5 m")
        if p[:4] != _DEFAULT_P[NAV_TAKEOFF]:
            hint["p"] = p[:4]
        if coordinate is not None and (self.home is None or list(coordinate) != self.home[:2]):
            hint["coordinate"] = list(coordinate)
        if not self.armed:
            self.add("arm", {})
            self.armed = True
        self.add("takeoff", {"altitude": alt, "qgc": hint})
        # The autopilot flies a take-off item to its altitude before the next item (PX4
        # User Guide, "Mission Mode (VTOL)": ascends to the take-off altitude, then heads
        # for the next position; in the air "a TAKEOFF item is treated as a normal
        # waypoint", "Mission Mode (Multicopter)", docs.px4.io). Our takeoff step does not
        # wait, and a leg sent during the climb is flown on a slant: the wait (default
        # tolerances, no pictures: the climb covers no ground) flies the plan level.
        self.body.append(("wait_for_flight", {}))
        self.sources.append(self.where)
        self.altitude = alt

    def land(self, p: list, hint: dict, coordinate: tuple[float, float], alt: float) -> None:
        """Land where the drone is, or fly to the landing spot first."""
        lat, lon = coordinate
        if p[:4] != _DEFAULT_P[NAV_LAND]:
            hint["p"] = p[:4]
        hint["coordinate"] = [lat, lon, alt]
        if (lat, lon) == self.position or (lat, lon) == (0, 0):
            self.add("land", {"qgc": hint})
        else:
            self.navigate(lat, lon, None, hint)
            self.add("wait_for_flight", {})
            self.add("land", {})
        self.altitude = 0.0

    def waypoint(
        self,
        command: Any,
        p: list,
        hint: dict,
        coordinate: tuple[float, float],
        alt: float,
        where: str,
    ) -> None:
        """Waypoint or loiter: the hold/loiter time becomes a sleep after arrival."""
        lat, lon = coordinate
        derived = (0, 1) if command == NAV_WAYPOINT else (0,)
        extra = [None if i in derived else value for i, value in enumerate(p[:4])]
        default = [None if i in derived else v for i, v in enumerate(_DEFAULT_P[command])]
        if extra != default:
            hint["p"] = extra
        self.navigate(lat, lon, alt, hint if len(hint) > 1 or command != NAV_WAYPOINT else None)
        accept = p[1] if command == NAV_WAYPOINT else 0
        self.add("wait_for_flight", {"horizontal_tolerance": accept} if accept else {})
        if p[0]:
            if p[0] < 0:
                raise QgcPlanError(f"{where}.params[0]", "hold time must not be negative")
            self.add("sleep", {"value": p[0]})


def read_geofence(data: Any) -> dict:
    """The plan's geoFence, checked by the flight envelope's rules (at least three
    vertices, no self-intersection, a positive radius)."""
    try:
        polygons, circles = parse_geofence(data)
    except EnvelopeError as exc:
        raise QgcPlanError(exc.field, exc.message) from None
    return {
        "polygons": [
            {"inclusion": p.inclusion, "polygon": [list(v) for v in p.points]} for p in polygons
        ],
        "circles": [
            {"inclusion": c.inclusion, "center": list(c.center), "radius": c.radius}
            for c in circles
        ],
    }


def geofence_json(fence: Mapping | None) -> dict:
    """A geofence as `QgcPlan.geofence` holds it → QGroundControl's `geoFence` object,
    written by the flight envelope's own writer."""
    fence = fence or {}
    shapes = Envelope(
        polygons=tuple(
            Polygon(p.get("inclusion", True), tuple(tuple(v) for v in p["polygon"]))
            for p in fence.get("polygons", [])
        ),
        circles=tuple(
            Circle(c.get("inclusion", True), tuple(c["center"]), c["radius"])
            for c in fence.get("circles", [])
        ),
    )
    return geofence_dict(shapes)


def _read_rally(data: Any) -> list[list[float]]:
    if data is None:
        return []
    points = []
    for i, raw in enumerate(_list(_obj(data, "rallyPoints").get("points", []), "rallyPoints")):
        where = f"rallyPoints.points[{i}]"
        raw = _list(raw, where)
        if len(raw) != 3:
            raise QgcPlanError(where, "must be [lat, lon, altitude]")
        lat, lon = _latlon(raw[0], raw[1], where)
        points.append([lat, lon, _num(raw[2], f"{where}[2]")])
    return points


def import_plan(source: str | bytes | Mapping, terrain: Terrain | None = None) -> QgcPlan:
    """A .plan file (text, bytes or parsed JSON) → QgcPlan, or QgcPlanError saying where.

    `terrain` (the imported terrain's elevation) turns heights above terrain into heights
    above home."""
    if isinstance(source, bytes | str):
        if len(source) > MAX_PLAN_BYTES:
            raise QgcPlanError("file", f"is over {MAX_PLAN_BYTES} bytes")
        try:
            source = json.loads(source)
        except (UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise QgcPlanError("file", f"is not JSON ({exc})") from None
        except RecursionError:
            raise QgcPlanError("file", "nests its JSON too deeply") from None
    plan = _obj(source, "file")
    if plan.get("fileType") != "Plan":
        raise QgcPlanError("fileType", f"must be 'Plan', got {plan.get('fileType')!r}")
    if plan.get("version") != 1:
        raise QgcPlanError("version", f"only version 1 is supported, got {plan.get('version')!r}")
    mission = _obj(plan.get("mission"), "mission")
    if mission.get("version") != 2:
        raise QgcPlanError(
            "mission.version", "only mission version 2 (QGroundControl 3.3+) is supported"
        )
    home = mission.get("plannedHomePosition")
    if home is not None:
        home = _list(home, "mission.plannedHomePosition")
        if len(home) != 3:
            raise QgcPlanError("mission.plannedHomePosition", "must be [lat, lon, altitude]")
        home = [
            *_latlon(home[0], home[1], "mission.plannedHomePosition"),
            _num(home[2], "mission.plannedHomePosition[2]"),
        ]
    firmware = int(_num(mission.get("firmwareType", 12), "mission.firmwareType"))
    reader = _Reader(home, terrain, firmware)
    items = _list(mission.get("items"), "mission.items")
    for i, raw in enumerate(items):
        reader.item(_obj(raw, f"mission.items[{i}]"), f"mission.items[{i}]", number=i + 1)
    if not reader.body:
        raise QgcPlanError("mission.items", "holds no mission item")
    steps = []
    for i, (command, params) in enumerate(reader.body):
        # The same checks a drone makes, so an imported plan is a startable mission.
        try:
            validate_command(command, params, mission=True)
        except ProtocolError as exc:
            raise QgcPlanError(reader.sources[i], exc.message) from None
        steps.append({"index": i, "command": command, "params": params})
    return QgcPlan(
        steps=steps,
        home=home,
        geofence=read_geofence(plan.get("geoFence")),
        rally_points=_read_rally(plan.get("rallyPoints")),
        cruise_speed=_optional(mission.get("cruiseSpeed"), "mission.cruiseSpeed"),
        hover_speed=_optional(mission.get("hoverSpeed"), "mission.hoverSpeed"),
        firmware_type=firmware,
        vehicle_type=int(_num(mission.get("vehicleType", 2), "mission.vehicleType")),
    )


# ---------------------------------------------------------------------------------------
# Writing.


def _coordinate_item(
    command: int, p4: list, lat: float, lon: float, alt: float, hint: Mapping
) -> dict:
    return {
        "AMSLAltAboveTerrain": None,
        "Altitude": alt,
        # Exported altitudes are always relative to home (frame 3).
        "AltitudeMode": ALTITUDE_MODE_RELATIVE,
        "autoContinue": hint.get("autoContinue", True),
        "command": command,
        "frame": FRAME_GLOBAL_RELATIVE_ALT,
        "params": [*p4, lat, lon, alt],
        "type": "SimpleItem",
    }


def _plain_item(command: int, params: list, hint: Mapping) -> dict:
    return {
        "autoContinue": hint.get("autoContinue", True),
        "command": command,
        "frame": hint.get("frame", FRAME_MISSION),
        "params": params,
        "type": "SimpleItem",
    }


def planned_home(steps: Sequence[Mapping], home: Sequence[float] | None) -> list[float]:
    """plannedHomePosition [lat, lon, AMSL alt]: the given home (a drone's, an imported
    plan's, the organisation's; altitude 0 when unknown), else the first waypoint's spot.
    QGroundControl refuses a plan without one."""
    if home is not None and len(home) >= 2:
        return [float(home[0]), float(home[1]), float(home[2]) if len(home) > 2 else 0.0]
    for step in steps:
        params = step.get("params") or {}
        if step.get("command") == "navigate":
            return [float(params["lat"]), float(params["lon"]), 0.0]
    raise QgcPlanError(
        "plannedHomePosition",
        "the mission has no waypoint and no home is known; fly it once or set the "
        "organisation's home first",
    )


class _Writer:
    def __init__(self, steps: Sequence[Mapping], home: Sequence[float], altitude: float) -> None:
        self.steps = [dict(s) for s in steps]
        self.home = home
        self.altitude = altitude
        self.position: tuple[float, float] | None = None
        self.items: list[dict] = []
        # The leg settings QGroundControl items have set so far.
        self.speed: float | None = None
        self.roi: list[float] | None = None
        self.photo_distance: float | None = None

    def _at(self, i: int, command: str) -> bool:
        return i < len(self.steps) and self.steps[i]["command"] == command

    def run(self) -> list[dict]:
        i = 0
        while i < len(self.steps):
            i = self.step(i)
        for n, item in enumerate(self.items, start=1):
            item["doJumpId"] = n
        return [dict(sorted(item.items())) for item in self.items]

    def step(self, i: int) -> int:
        step = self.steps[i]
        command = step["command"]
        params = dict(step.get("params") or {})
        hint = params.get("qgc") or {}
        where = f"steps[{i}] (index {step.get('index')})"
        if command in ("arm", "wait_for_flight"):
            # A QGC mission arms with its takeoff, and every nav item waits for arrival.
            return i + 1
        if command == "takeoff":
            self.altitude = float(params.get("altitude", DEFAULT_ALTITUDE))
            if hint.get("implied"):  # the climb to the first item's altitude, no item itself
                return i + 1
            lat, lon = hint.get("coordinate") or self.home[:2]
            code = hint.get("command", NAV_TAKEOFF)
            p4 = hint.get("p", _DEFAULT_P[code])
            self.items.append(_coordinate_item(code, p4, lat, lon, self.altitude, hint))
            return i + 1
        if command == "takepic":
            code = hint.get("command", IMAGE_START_CAPTURE)
            p = hint.get("p", _DEFAULT_CAMERA[code])
            self.items.append(_plain_item(code, list(p), hint))
            return i + 1
        if command == "land":
            lat, lon, alt = hint.get("coordinate") or (*(self.position or self.home[:2]), 0)
            code = hint.get("command", NAV_LAND)
            p4 = hint.get("p", _DEFAULT_P[code])
            self.items.append(_coordinate_item(code, p4, lat, lon, alt, hint))
            self.altitude = 0.0
            return i + 1
        if command == "navigate":
            return self.navigate(i, params, hint)
        if command == "sleep":
            if self.position is None:
                raise QgcPlanError(where, "a sleep before any waypoint has no QGroundControl item")
            lat, lon = self.position
            p4 = [float(params["value"]), 0, 0, None]
            self.items.append(_coordinate_item(NAV_LOITER_TIME, p4, lat, lon, self.altitude, {}))
            return i + 1
        raise QgcPlanError(where, f"the {command!r} step has no QGroundControl mission item")

    def settings(self, params: Mapping, wait: Mapping) -> None:
        """The speed, region of interest and camera trigger items a leg needs first."""
        speed = params.get("speed")
        if speed is not None and speed != self.speed:
            self.items.append(_plain_item(DO_CHANGE_SPEED, [1, speed, -1, 0, 0, 0, 0], {}))
            self.speed = speed
        roi = params.get("roi")
        roi = list(roi) if roi is not None else None
        if roi != self.roi:
            if roi is None:
                self.items.append(_plain_item(DO_SET_ROI_NONE, [0] * 7, {}))
            else:
                item = _coordinate_item(DO_SET_ROI_LOCATION, [0, 0, 0, 0], *roi, 0, {})
                self.items.append(item)
            self.roi = roi
        distance = wait.get("photo_distance")
        if distance != self.photo_distance:
            params7 = [distance or 0, 0, 0, 0, 0, 0, 0]
            self.items.append(_plain_item(DO_SET_CAM_TRIGG_DIST, params7, {}))
            self.photo_distance = distance

    def navigate(self, i: int, params: dict, hint: Mapping) -> int:
        lat, lon = float(params["lat"]), float(params["lon"])
        code = hint.get("command", NAV_WAYPOINT)
        j = i + 1
        wait: Mapping = {}
        if self._at(j, "wait_for_flight"):
            wait = self.steps[j].get("params") or {}
            j += 1
        self.settings(params, wait)
        if code in (NAV_RETURN_TO_LAUNCH, *LAND_COMMANDS) and self._at(j, "land"):
            if code == NAV_RETURN_TO_LAUNCH:
                self.items.append(_plain_item(NAV_RETURN_TO_LAUNCH, hint.get("p", [0] * 7), hint))
            else:
                _, _, alt = hint.get("coordinate", (lat, lon, 0))
                p4 = hint.get("p", _DEFAULT_P[code])
                self.items.append(_coordinate_item(code, p4, lat, lon, alt, hint))
            self.position, self.altitude = (lat, lon), 0.0
            return j + 1
        self.altitude += float(params.get("altitude_delta") or 0.0)
        hold = 0.0
        if self._at(j, "sleep"):
            hold = float(self.steps[j]["params"]["value"])
            j += 1
        if code == NAV_LOITER_TIME:
            p4 = list(hint.get("p", _DEFAULT_P[NAV_LOITER_TIME]))
            p4[0] = hold
        else:
            code = NAV_WAYPOINT
            p4 = list(hint.get("p", _DEFAULT_P[NAV_WAYPOINT]))
            p4[0] = hold
            p4[1] = wait.get("horizontal_tolerance", 0)
        self.items.append(_coordinate_item(code, p4, lat, lon, self.altitude, hint))
        self.position = (lat, lon)
        return j


def export_plan(
    steps: Sequence[Mapping],
    *,
    home: Sequence[float] | None = None,
    geofence: Mapping | None = None,
    rally_points: Sequence[Sequence[float]] = (),
    cruise_speed: float | None = 15,
    hover_speed: float | None = 5,
    firmware_type: int = 12,
    vehicle_type: int = 2,
    altitude: float = DEFAULT_ALTITUDE,
) -> dict:
    """Our steps (in flying order) → a .plan document (a dict; `dumps` writes the file).

    `home` is [lat, lon(, AMSL alt)] (see planned_home). `altitude` is the height the drone
    is at if the steps do not start with a takeoff. Steps with no QGroundControl item
    (sense, changeN, virtualalarm, …) raise QgcPlanError.
    """
    planned = planned_home(steps, home)
    items = _Writer(steps, planned, altitude).run()
    return {
        "fileType": "Plan",
        "geoFence": geofence_json(geofence),
        "groundStation": "Skyhive",
        "mission": {
            "cruiseSpeed": 15 if cruise_speed is None else cruise_speed,
            "firmwareType": firmware_type,
            "globalPlanAltitudeMode": ALTITUDE_MODE_RELATIVE,
            "hoverSpeed": 5 if hover_speed is None else hover_speed,
            "items": items,
            "plannedHomePosition": planned,
            "vehicleType": vehicle_type,
            "version": 2,
        },
        "rallyPoints": {"points": [list(p) for p in rally_points], "version": 2},
        "version": 1,
    }


def export_qgc_plan(plan: QgcPlan) -> dict:
    """Re-export an imported plan with its home, geofence, rally points and speeds."""
    return export_plan(
        plan.steps,
        home=plan.home,
        geofence=plan.geofence,
        rally_points=plan.rally_points,
        cruise_speed=plan.cruise_speed,
        hover_speed=plan.hover_speed,
        firmware_type=plan.firmware_type,
        vehicle_type=plan.vehicle_type,
    )


def dumps(document: Mapping) -> str:
    """The file text, indented as QGroundControl writes it."""
    return json.dumps(document, indent=4, sort_keys=True) + "\n"
