"""The telemetry API and websocket: organisation isolation, shapes, CSV export."""

from __future__ import annotations

import csv
import io
import time
from datetime import UTC, datetime

import psycopg
import pytest
from rest_framework.test import APIClient

from telemetry import queries, storage
from telemetry.storage import Sample
from tests.support.websocket import connect_websocket

# Within raw retention, on a whole minute.
T0 = float(int(time.time() // 60 * 60) - 3600)


def _iso(ts: float) -> str:
    return datetime.fromtimestamp(ts, UTC).isoformat()


def api(user) -> APIClient:
    client = APIClient()
    client.force_authenticate(user)
    return client


def _store(samples: list[Sample]) -> None:
    with psycopg.connect(queries.conninfo_from_settings(), autocommit=True) as conn:
        storage.copy_samples(conn, samples)


@pytest.fixture
def flown(world_tx):
    pk, other = world_tx.drone.pk, world_tx.other_drone.pk
    _store(
        [Sample(T0 + i * 0.1, pk, "Gyros", {"x": float(i), "y": -float(i)}) for i in range(100)]
        + [Sample(T0, pk, "FlightBatteryState", {"Voltage": 15.9, "Current": 11.0})]
        + [Sample(T0, other, "Gyros", {"x": 42.0})]
    )
    return world_tx


def test_a_member_reads_the_latest_value_of_every_object(flown):
    body = api(flown.viewer).get("/api/v1/telemetry/drones/ACME_1/latest/").json()
    assert body["drone_id"] == "ACME_1"
    assert body["objects"]["Gyros"]["fields"] == {"x": 99.0, "y": -99.0}
    assert body["objects"]["FlightBatteryState"]["fields"]["Voltage"] == 15.9


@pytest.mark.parametrize(
    "path", ["latest/", "range/?object=Gyros&fields=x&start=0&end=1", "export.csv?start=0&end=1"]
)
def test_another_organisations_drone_is_not_found_in_any_telemetry_endpoint(flown, path):
    response = api(flown.owner).get(f"/api/v1/telemetry/drones/GLOBEX_1/{path}")
    assert response.status_code == 404
    assert response.json()["code"] == "not_found"


def test_the_telemetry_api_requires_authentication(flown):
    response = APIClient().get("/api/v1/telemetry/drones/ACME_1/latest/")
    assert response.status_code in (401, 403)


def test_a_range_comes_back_as_columns_of_buckets(flown):
    response = api(flown.viewer).get(
        "/api/v1/telemetry/drones/ACME_1/range/",
        {"object": "Gyros", "fields": "x,y", "start": T0, "end": T0 + 10, "points": 10},
    )
    body = response.json()
    assert response.status_code == 200, body
    assert body["bucket_s"] == 1.0 and body["source"] == "raw"
    assert body["count"] == [10] * 10
    assert body["series"]["x"]["avg"][0] == pytest.approx(4.5)
    assert body["series"]["y"]["min"][9] == -99.0


def test_a_bad_range_answers_400_naming_the_field(flown):
    response = api(flown.viewer).get(
        "/api/v1/telemetry/drones/ACME_1/range/",
        {"object": "Gyros", "fields": "x", "start": T0 + 10, "end": T0},
    )
    assert response.status_code == 400
    assert "end" in response.json()["fields"]
    response = api(flown.viewer).get(
        "/api/v1/telemetry/drones/ACME_1/range/",
        {"object": "Gyros", "fields": "x;drop", "start": T0, "end": T0 + 1},
    )
    assert response.status_code == 400 and "fields" in response.json()["fields"]


def test_a_range_is_exported_as_csv_with_one_column_per_field(flown):
    response = api(flown.viewer).get(
        "/api/v1/telemetry/drones/ACME_1/export.csv",
        {"object": "Gyros", "fields": "x,y", "start": T0, "end": _iso(T0 + 5)},
    )
    assert response.status_code == 200
    assert response["Content-Type"].startswith("text/csv")
    rows = list(csv.reader(io.StringIO(b"".join(response.streaming_content).decode())))
    assert rows[0] == ["ts", "x", "y"]
    assert len(rows) == 1 + 50
    assert rows[1][0] == _iso(T0)
    assert rows[2][1:] == ["1.0", "-1.0"]


def test_the_api_schema_documents_the_telemetry_endpoints(world):
    schema = api(world.viewer).get("/api/schema/", {"format": "json"}).json()
    assert "/api/v1/telemetry/drones/{drone_id}/range/" in schema["paths"]
    assert "/api/v1/telemetry/drones/{drone_id}/latest/" in schema["paths"]


async def _connect(user, drone_id: str):
    return await connect_websocket(f"/ws/telemetry/{drone_id}/", user)


@pytest.mark.django_db(transaction=True)
async def test_the_live_websocket_sends_a_snapshot_then_throttled_updates(flown):
    from asgiref.sync import sync_to_async

    from telemetry.live import ChannelsLivePublisher

    socket, connected, _ = await _connect(flown.viewer, "ACME_1")
    try:
        assert connected
        snapshot = await socket.receive_json_from(timeout=5)
        assert snapshot["type"] == "snapshot"
        assert snapshot["objects"]["Gyros"]["fields"]["x"] == 99.0
        publish = await sync_to_async(ChannelsLivePublisher, thread_sensitive=False)()
        await sync_to_async(publish, thread_sensitive=False)(
            {
                flown.drone.pk: {"Gyros": (T0 + 20, {"x": 7.0})},
                flown.other_drone.pk: {"Gyros": (T0 + 20, {"x": 8.0})},
            }
        )
        update = await socket.receive_json_from(timeout=5)
        assert update == {
            "type": "update",
            "objects": {"Gyros": {"ts": T0 + 20, "fields": {"x": 7.0}}},
        }
        assert await socket.receive_nothing(timeout=0.3)
    finally:
        await socket.disconnect()


@pytest.mark.django_db(transaction=True)
async def test_an_outsider_cannot_open_the_live_websocket_of_a_drone(flown):
    socket, connected, code = await _connect(flown.outsider, "ACME_1")
    assert not connected
    assert code == 4403
    await socket.disconnect()
