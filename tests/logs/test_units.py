"""Units in the log viewer's API: each format's own metadata (PX4 ULog field names, ArduPilot
FMTU units and multipliers, DFI unit attributes) gives the recorded unit; the API shows
m, m/s, °, %, V and A, with the values converted."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from logs import services
from logs.store import import_to_store
from logs.synth import dataflash_dtype, write_dataflash
from logs.units import display, ulog_unit
from tests.logs.dfi_builder import DESCRIPTION, write_dfi

ULOG = Path(__file__).resolve().parents[1] / "data" / "ulog" / "sample_log_small.ulg"


def summary(store) -> dict[str, dict]:  # type: ignore[no-untyped-def]
    return {s["path"]: s for s in services.series_list(store)}


def first_values(store, path: str) -> tuple[list, list, str]:  # type: ignore[no-untyped-def]
    """(recorded values, shown values, shown unit) of one series."""
    _, recorded = store.read(path)
    shown = services.plot(store, path)
    return list(np.asarray(recorded)[:5]), shown["v"][:5], shown["unit"]


@pytest.mark.parametrize(
    "unit, shown, factor",
    [("mm", "m", 1e-3), ("rad", "°", 180 / math.pi), ("fraction", "%", 100.0), ("mV", "V", 1e-3),
     ("cA", "A", 0.01), ("degE7", "°", 1e-7), ("m/s", "m/s", 1.0), ("PWM", "PWM", 1.0)],
)  # fmt: skip
def test_recorded_units_are_shown_in_si_style(unit, shown, factor):
    assert display(unit).unit == shown
    assert display(unit).factor == pytest.approx(factor)


def test_px4_field_names_give_their_units():
    assert ulog_unit("battery_status", "voltage_v") == "V"
    assert ulog_unit("battery_status", "current_a") == "A"
    assert ulog_unit("battery_status", "remaining") == "fraction"
    assert ulog_unit("vehicle_gps_position", "alt") == "mm"
    assert ulog_unit("vehicle_gps_position", "lat") == "degE7"
    assert ulog_unit("vehicle_local_position", "vx") == "m/s"
    assert ulog_unit("sensor_combined", "gyro_rad[2]") == "rad"
    assert ulog_unit("sensor_combined", "accelerometer_m_s2[0]") == "m/s/s"
    assert ulog_unit("vehicle_status", "nav_state") == ""


def test_a_real_px4_log_is_shown_in_metres_percent_volts_and_degrees(tmp_path):
    store = import_to_store(ULOG, tmp_path / "store")
    series = summary(store)
    expected = {
        "battery_status_0/voltage_v": ("V", "V", 1.0),
        "battery_status_0/current_a": ("A", "A", 1.0),
        "battery_status_0/remaining": ("fraction", "%", 100.0),
        "vehicle_gps_position/alt": ("mm", "m", 1e-3),
        "vehicle_local_position/z": ("m", "m", 1.0),
        "vehicle_local_position/vx": ("m/s", "m/s", 1.0),
        "vehicle_attitude/euler/roll": ("rad", "°", 180 / math.pi),
    }
    for path, (recorded_unit, unit, factor) in expected.items():
        assert (series[path]["recorded_unit"], series[path]["unit"]) == (recorded_unit, unit)
        recorded, shown, shown_unit = first_values(store, path)
        assert shown_unit == unit
        assert shown == pytest.approx([float(v) * factor for v in recorded]), path
    # A 4-cell pack near 16 V and an altitude near 0.5 km, no longer 66 000 "mm" beside it.
    assert 10 < services.plot(store, "battery_status_0/voltage_v")["v"][0] < 30
    assert abs(services.plot(store, "vehicle_gps_position/alt")["v"][0]) < 10_000
    values = services.values_at_time(store, series["battery_status_0/remaining"]["end"])
    remaining = values["battery_status_0"]["remaining"]["value"]
    assert 0 <= remaining <= 100 and remaining > 1  # percent, not a fraction


def test_dataflash_units_and_multipliers_come_from_unit_mult_and_fmtu(tmp_path):
    """Alt stored in cm ('i', multiplier 1e-2), Volt in mV ('H', 1e-3), Ang in centidegrees
    ('c': the format scales it, so FMTU's 1e-2 must not apply twice), RemPct as it is."""
    messages: dict[str, tuple[str, np.ndarray]] = {}

    def message(name: str, chars: str, columns: str, rows: list[tuple]) -> None:
        arr = np.zeros(len(rows), dtype=dataflash_dtype(chars, columns.split(",")))
        for i, row in enumerate(rows):
            arr[i] = row
        messages[name] = (chars, arr)

    units = {"s": "s", "m": "m", "n": "m/s", "v": "V", "d": "deg", "%": "%", "-": ""}
    mults = {"-": 0.0, "?": 1.0, "B": 1e-2, "C": 1e-3, "F": 1e-6}
    message("UNIT", "QbZ", "TimeUS,Id,Label", [(0, ord(k), v.encode()) for k, v in units.items()])
    message("MULT", "Qbd", "TimeUS,Id,Mult", [(0, ord(k), v) for k, v in mults.items()])
    # write_dataflash numbers the messages from 129 in this order: CTUN is 132.
    message("FMTU", "QBNN", "TimeUS,FmtType,UnitIds,MultIds", [(0, 132, b"smnvd%", b"FBBCB-")])
    message(
        "CTUN", "QihHcB", "TimeUS,Alt,Crt,Volt,Ang,RemPct",
        [(1_000_000, 1234, -250, 15800, 4500, 87), (2_000_000, 1300, 100, 15700, -9000, 86)],
    )  # fmt: skip
    write_dataflash(tmp_path / "flight.bin", messages)
    store = import_to_store(tmp_path / "flight.bin", tmp_path / "store")
    series = summary(store)
    shown = {p: services.plot(store, p) for p in series if p.startswith("CTUN/")}
    assert {p: (s["unit"], pytest.approx(s["v"])) for p, s in shown.items()} == {
        "CTUN/Alt": ("m", [12.34, 13.0]),
        "CTUN/Crt": ("m/s", [-2.5, 1.0]),
        "CTUN/Volt": ("V", [15.8, 15.7]),
        "CTUN/Ang": ("°", [45.0, -90.0]),
        "CTUN/RemPct": ("%", [87, 86]),
    }


def test_dfi_unit_attributes_are_converted(tmp_path):
    description = DESCRIPTION.replace('name="Altitude" unit="m"', 'name="Altitude" unit="mm"')
    store = import_to_store(write_dfi(tmp_path / "f.dfi", description=description), tmp_path / "s")
    series = summary(store)
    assert (series["navdata/Altitude"]["recorded_unit"], series["navdata/Altitude"]["unit"]) == (
        "mm", "m",
    )  # fmt: skip
    assert services.plot(store, "navdata/Altitude")["v"] == pytest.approx([5e-4, 7.5e-4, 1.25e-3])
    assert series["navdata/Rotation/roll"]["unit"] == "°"
    assert services.plot(store, "navdata/Rotation/roll")["v"] == [1.5, 1.0, 0.5]
    assert series["commands/Velocity/x"]["unit"] == "m/s"
    assert series["navdata/state"]["unit"] == ""  # an enumeration stays as it is
