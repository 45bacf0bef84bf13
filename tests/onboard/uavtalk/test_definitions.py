"""The project's own UAVObject XML, hashed here with dRonin's object-id algorithm written
out afresh from its generator (ground/uavobjgenerator/uavobjectparser.cpp: parent=
option lists, the stable sort by element size, the shift-add-XOR hash), must give the ids
the firmware uses (docs/uavtalk.md "Object ids"). Independent of onboard.uavtalk.objects,
so a slip in the agent's own hashing cannot hide a wrong definition."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from onboard.uavtalk import ObjectRegistry, default_objects_dir

DATA = Path(__file__).resolve().parents[2] / "data" / "uavtalk"

# dRonin Release-20180729's ids (docs/uavtalk.md, from dRonin's own Python API).
RELEASE_IDS = {
    "GCSTelemetryStats": 0xABC72744,
    "FlightTelemetryStats": 0x2F7E2902,
    "FlightStatus": 0x4D924972,
    "GPSPosition": 0x5C1D189E,
    "AttitudeActual": 0x33DAD5E6,
    "PositionActual": 0xFA9E2D42,
    "VelocityActual": 0x5A08F61A,
    "FlightBatteryState": 0xCAC62F5E,
    "Waypoint": 0xE02C8266,
    "PathDesired": 0x3AF5274A,
    "HomeLocation": 0xCA32B032,
    "SystemStats": 0xE1DF2D70,
    "Accels": 0xDD9D5FC0,
    "Gyros": 0x04228AF6,
    "BaroAltitude": 0x99622E6A,
    "FirmwareIAPObj": 0x5E6E8FDC,
    "UAVTalkReceiver": 0x0D2720A4,
    "ManualControlCommand": 0x1C994034,
    "ManualControlSettings": 0x884ED0E6,
}
# dRonin's latest source (next, 2021): only ManualControlSettings differs (RssiType IBus).
LATEST_IDS = {**RELEASE_IDS, "ManualControlSettings": 0x3C35BE0E}
SIZES = {"int8": 1, "int16": 2, "int32": 4, "uint8": 1, "uint16": 2, "uint32": 4,
         "float": 4, "enum": 1}  # fmt: skip
TYPES = list(SIZES)


def _hash(h: int, value: int) -> int:
    return (h ^ ((h << 5) + (h >> 2) + value)) & 0xFFFFFFFF


def _hash_text(h: int, text: str) -> int:
    for byte in text.encode("latin-1"):
        h = _hash(h, byte)
    return h


def _options(field: ET.Element) -> list[str]:
    listed = [o.text.strip() for o in field.iter("option") if o.text]
    return listed or [o.strip() for o in field.get("options", "").split(",") if o.strip()]


def _elements(field: ET.Element) -> int:
    names = [e for e in field.iter("elementname")]
    listed = [n for n in field.get("elementnames", "").split(",") if n.strip()]
    return len(names) or len(listed) or int(field.get("elements", "1"))


def _fields(files: list[Path]) -> dict[str, tuple[ET.Element, list[ET.Element]]]:
    objects = {}
    for file in files:
        for obj in ET.parse(file).getroot().iter("object"):
            objects[obj.get("name")] = (obj, list(obj.iter("field")))
    return objects


def _field(objects: dict, path: str) -> ET.Element:
    obj_name, _, field_name = path.partition(".")
    return next(f for f in objects[obj_name][1] if f.get("name") == field_name)


def _enum(objects: dict, field: ET.Element) -> tuple[list[str], list[str]]:
    """(options, root options): no options of its own means its parent's."""
    parent = (field.get("parent") or "").strip()
    if not parent:
        return _options(field), _options(field)
    inherited, root = _enum(objects, _field(objects, parent))
    return _options(field) or inherited, root


def dronin_id(objects: dict, name: str) -> int:
    obj, fields = objects[name]
    h = _hash_text(0, name)
    h = _hash(h, obj.get("settings") == "true")
    h = _hash(h, obj.get("singleinstance") == "true")
    # Python's sort is stable, as std::stable_sort: wire order, largest elements first.
    for field in sorted(fields, key=lambda f: -SIZES[f.get("type")]):
        h = _hash_text(h, field.get("name"))
        h = _hash(h, _elements(field))
        h = _hash(h, TYPES.index(field.get("type")))
        if field.get("type") == "enum":
            options, root = _enum(objects, field)
            expected = 0
            for option in options:
                index = root.index(option)
                if index != expected:  # a gap in a parent's list is hashed
                    h = _hash(h, index)
                expected = index + 1
                h = _hash_text(h, option)
    return h & 0xFFFFFFFE


def _project(folder: str) -> dict:
    base = default_objects_dir()
    return _fields(
        sorted(base.glob("*.xml")) + sorted((base / "generations" / folder).glob("*.xml"))
    )


def _wrong(objects: dict, expected: dict[str, int]) -> dict[str, str]:
    found = {name: dronin_id(objects, name) for name in expected}
    return {
        n: f"{found[n]:#010x} != {expected[n]:#010x}" for n in expected if found[n] != expected[n]
    }


@pytest.mark.parametrize(
    ("folder", "expected"), [("Release-20180729", RELEASE_IDS), ("next-2021", LATEST_IDS)]
)
def test_the_projects_xml_hashes_to_the_firmwares_ids(folder: str, expected: dict) -> None:
    assert _wrong(_project(folder), expected) == {}


def test_the_check_catches_the_definition_the_agent_used_to_send() -> None:
    objects = _project("Release-20180729")
    before = ["manualcontrolsettings.before.xml", "shareddefs.before.xml"]
    objects.update(_fields([DATA / name for name in before]))
    assert dronin_id(objects, "ManualControlSettings") == 0x3B9DB004
    assert list(_wrong(objects, RELEASE_IDS)) == ["ManualControlSettings"]


def test_the_agent_computes_the_same_ids_for_both_generations() -> None:
    registry = ObjectRegistry.load(every_generation=True)
    for key, expected in (("release", RELEASE_IDS), ("latest", LATEST_IDS)):
        ids = {name: registry.for_generation(key)[name].id for name in expected}
        assert ids == expected, key


def test_a_board_of_one_generation_knows_only_its_own_manual_control_settings() -> None:
    release = ObjectRegistry.load(generation="release")
    assert LATEST_IDS["ManualControlSettings"] not in release.by_id
    agent = ObjectRegistry.load(every_generation=True)
    assert {agent.by_id[i].name for i in (0x884ED0E6, 0x3C35BE0E)} == {"ManualControlSettings"}
    assert agent["ManualControlSettings"].id == RELEASE_IDS["ManualControlSettings"]


def test_an_unknown_generation_is_refused_with_the_known_ones() -> None:
    with pytest.raises(ValueError, match="release, latest"):
        ObjectRegistry.load(generation="2016")
