"""The CSV export: one column per field by default (every field stored in the range, or
the ones asked for), the JSON-column form on request, bad layouts refused."""

from __future__ import annotations

import csv
import io

import pytest

from telemetry.storage import Sample
from tests.telemetry.test_api import T0, _iso, _store, api

URL = "/api/v1/telemetry/drones/ACME_1/export.csv"


@pytest.fixture
def samples(world_tx):
    pk = world_tx.drone.pk
    _store(
        [Sample(T0 + i, pk, "Gyros", {"x": float(i), "y": -float(i) - 1}) for i in range(3)]
        + [Sample(T0 + 0.5, pk, "FlightBatteryState", {"Voltage": 15.9, "Current": 11.0})]
        + [Sample(T0 + 1.5, pk, "GPSPosition", {"Status": "Fix3D", "Cells": [1, 2]})]
        + [Sample(T0, world_tx.other_drone.pk, "Gyros", {"x": 42.0, "secret": 1.0})]
    )
    return world_tx


def rows(user, **params) -> list[list[str]]:  # type: ignore[no-untyped-def]
    response = api(user).get(URL, {"start": T0, "end": T0 + 10, **params})
    assert response.status_code == 200, response.content
    return list(csv.reader(io.StringIO(b"".join(response.streaming_content).decode())))


def test_the_default_export_has_one_column_per_object_field(samples):
    table = rows(samples.viewer)
    assert table[0] == [
        "ts", "object", "FlightBatteryState.Current", "FlightBatteryState.Voltage",
        "GPSPosition.Cells", "GPSPosition.Status", "Gyros.x", "Gyros.y",
    ]  # fmt: skip
    assert table[1] == [_iso(T0), "Gyros", "", "", "", "", "0.0", "-1.0"]
    assert table[2] == [_iso(T0 + 0.5), "FlightBatteryState", "11.0", "15.9", "", "", "", ""]
    assert table[4] == [_iso(T0 + 1.5), "GPSPosition", "", "", "[1,2]", "Fix3D", "", ""]
    assert len(table) == 1 + 5  # another organisation's drone adds no row and no column


def test_one_object_gets_its_fields_as_plain_columns(samples):
    table = rows(samples.viewer, object="Gyros")
    assert table[0] == ["ts", "x", "y"]
    assert table[1:] == [[_iso(T0 + i), str(float(i)), str(-float(i) - 1)] for i in range(3)]
    assert rows(samples.viewer, object="Gyros", fields="y")[1] == [_iso(T0), "-1.0"]


def test_the_json_column_form_on_request(samples):
    table = rows(samples.viewer, layout="long")
    assert table[0] == ["ts", "object", "fields"]
    assert table[2] == [_iso(T0 + 0.5), "FlightBatteryState", '{"Current":11.0,"Voltage":15.9}']


@pytest.mark.parametrize(
    "params, field",
    [
        ({"layout": "tall"}, "layout"),
        ({"layout": "long", "object": "Gyros", "fields": "x"}, "fields"),
    ],
)
def test_a_bad_layout_is_refused_naming_the_field(samples, params, field):
    response = api(samples.viewer).get(URL, {"start": T0, "end": T0 + 10, **params})
    assert response.status_code == 400 and field in response.json()["fields"]


def test_an_empty_range_exports_just_the_header(samples):
    response = api(samples.viewer).get(URL, {"start": T0 + 100, "end": T0 + 200})
    assert b"".join(response.streaming_content).decode().splitlines() == ["ts,object"]
