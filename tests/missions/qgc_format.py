"""What QGroundControl's loaders demand of a `.plan` file, written down as checks.

Each rule follows the keys and JSON types QGroundControl validates when it opens a plan
(JsonHelper::validateExternalQGCJsonFile, PlanMasterController, MissionController's
_loadJsonMissionFileV2, MissionItem/SimpleMissionItem::load, GeoFenceController,
QGCFencePolygon, QGCFenceCircle, RallyPointController): a file that breaks one is refused
there. `plan_errors` returns every broken rule; an empty list means QGroundControl loads it.
"""

from __future__ import annotations

from typing import Any

# QGroundControl's JSON types: "Double" is any JSON number, "Null" accepts a number or null.
NUMBER = "number"
NUMBER_OR_NULL = "number or null"


def _is(value: Any, kind: Any) -> bool:
    if kind == NUMBER:
        return isinstance(value, int | float) and not isinstance(value, bool)
    if kind == NUMBER_OR_NULL:
        return value is None or _is(value, NUMBER)
    return isinstance(value, kind)


def _keys(obj: Any, where: str, rules: list[tuple[str, Any, bool]], errors: list[str]) -> bool:
    """validateKeys: each (key, type, required); False when obj is not an object."""
    if not isinstance(obj, dict):
        errors.append(f"{where}: not an object")
        return False
    for key, kind, required in rules:
        if key not in obj:
            if required:
                errors.append(f"{where}.{key}: missing")
        elif not _is(obj[key], kind):
            errors.append(f"{where}.{key}: {obj[key]!r} is not a {getattr(kind, '__name__', kind)}")
    return True


def _coordinate(value: Any, where: str, errors: list[str], *, altitude: bool) -> None:
    """JsonHelper::loadGeoCoordinate: [lat, lon] or [lat, lon, alt] of numbers."""
    size = 3 if altitude else 2
    if not (isinstance(value, list) and len(value) == size and all(_is(v, NUMBER) for v in value)):
        errors.append(f"{where}: {value!r} is not [{'lat, lon, alt' if altitude else 'lat, lon'}]")


def _simple_item(item: dict, where: str, errors: list[str]) -> None:
    _keys(
        item,
        where,
        [
            ("type", str, True),
            ("frame", NUMBER, True),
            ("command", NUMBER, True),
            ("params", list, True),
            ("autoContinue", bool, True),
            ("doJumpId", NUMBER, False),
        ],
        errors,
    )
    params = item.get("params")
    if isinstance(params, list) and (
        len(params) != 7 or not all(_is(p, NUMBER_OR_NULL) for p in params)
    ):
        errors.append(f"{where}.params: must be 7 numbers (null for NaN)")
    altitude_keys = ("AltitudeMode", "Altitude", "AMSLAltAboveTerrain")
    if any(key in item for key in altitude_keys):
        _keys(
            item,
            where,
            [
                ("AltitudeMode", NUMBER, True),
                ("Altitude", NUMBER, True),
                ("AMSLAltAboveTerrain", NUMBER_OR_NULL, True),
            ],
            errors,
        )


def _mission(mission: Any, errors: list[str]) -> None:
    if not _keys(
        mission,
        "mission",
        [
            ("version", NUMBER, True),
            ("plannedHomePosition", list, True),
            ("items", list, True),
            ("firmwareType", NUMBER, True),
            ("vehicleType", NUMBER, False),
            ("cruiseSpeed", NUMBER, False),
            ("hoverSpeed", NUMBER, False),
            ("globalPlanAltitudeMode", NUMBER, False),
        ],
        errors,
    ):
        return
    if mission.get("version") != 2:
        errors.append("mission.version: must be 2")
    _coordinate(
        mission.get("plannedHomePosition"), "mission.plannedHomePosition", errors, altitude=True
    )
    for i, item in enumerate(mission.get("items") or []):
        where = f"mission.items[{i}]"
        if not _keys(item, where, [("type", str, True)], errors):
            continue
        if item["type"] == "SimpleItem":
            _simple_item(item, where, errors)
        elif item["type"] == "ComplexItem":
            _keys(item, where, [("complexItemType", str, True)], errors)
        else:
            errors.append(f"{where}.type: unknown item type {item['type']!r}")


def _fence(fence: Any, errors: list[str]) -> None:
    rules = [("version", NUMBER, True), ("circles", list, True), ("polygons", list, True)]
    if not _keys(fence, "geoFence", rules, errors):
        return
    if fence.get("version") != 2:
        errors.append("geoFence.version: must be 2")
    for i, polygon in enumerate(fence.get("polygons") or []):
        where = f"geoFence.polygons[{i}]"
        rules = [("version", NUMBER, True), ("inclusion", bool, True), ("polygon", list, True)]
        if _keys(polygon, where, rules, errors):
            points = polygon.get("polygon") or []
            if len(points) < 3:
                errors.append(f"{where}.polygon: fewer than three vertices")
            for j, point in enumerate(points):
                _coordinate(point, f"{where}.polygon[{j}]", errors, altitude=False)
    for i, circle in enumerate(fence.get("circles") or []):
        where = f"geoFence.circles[{i}]"
        rules = [("version", NUMBER, True), ("inclusion", bool, True), ("circle", dict, True)]
        if _keys(circle, where, rules, errors):
            inner = circle["circle"]
            rules = [("center", list, True), ("radius", NUMBER, True)]
            if _keys(inner, f"{where}.circle", rules, errors):
                _coordinate(inner["center"], f"{where}.circle.center", errors, altitude=False)


def _rally(rally: Any, errors: list[str]) -> None:
    rules = [("version", NUMBER, True), ("points", list, True)]
    if not _keys(rally, "rallyPoints", rules, errors):
        return
    if rally.get("version") != 2:
        errors.append("rallyPoints.version: must be 2")
    for i, point in enumerate(rally.get("points") or []):
        _coordinate(point, f"rallyPoints.points[{i}]", errors, altitude=True)


def plan_errors(document: Any) -> list[str]:
    """Every rule of QGroundControl's plan loaders the document breaks."""
    errors: list[str] = []
    rules = [
        ("fileType", str, True),
        ("version", NUMBER, True),
        ("groundStation", str, True),
        ("mission", dict, True),
        ("geoFence", dict, True),
        ("rallyPoints", dict, True),
    ]
    if not _keys(document, "file", rules, errors):
        return errors
    if document.get("fileType") != "Plan":
        errors.append("fileType: must be 'Plan'")
    if document.get("version") != 1:
        errors.append("version: must be 1")
    _mission(document.get("mission"), errors)
    _fence(document.get("geoFence"), errors)
    _rally(document.get("rallyPoints"), errors)
    return errors
