"""/health on the real services: the status word for anyone, the details for staff, the
checks cached, the broker's state read from what the gateways report."""

import paho.mqtt.client as mqtt
import pytest
from django.contrib.auth.models import User
from django.test import Client

from config import health
from runtime.processes import wait_for


@pytest.fixture(autouse=True)
def _fresh_checks():
    health.forget()
    yield
    health.forget()


@pytest.fixture
def staff(db):
    client = Client()
    client.force_login(User.objects.create_user("operations", is_staff=True))
    return client


@pytest.fixture
def linked(gateway, broker):
    """A gateway whose link to the broker is up, as it reports it in Redis."""
    address = f"127.0.0.1:{broker.port}"
    wait_for(lambda: health.check_mosquitto() == {address: None}, timeout=15)
    return gateway


def test_anonymous_callers_get_only_the_status_word(db, linked):
    response = Client().get("/health")
    assert response.status_code == 200
    assert response.json() == {"status": "ok"}


def test_staff_get_every_part_and_the_process_counters(staff, linked):
    body = staff.get("/health").json()
    assert body["status"] == "ok"
    assert body["checks"] == {"database": "ok", "redis": "ok", "broker": "ok"}
    assert isinstance(body["processes"], dict)


def test_no_request_opens_an_mqtt_connection(db, linked, monkeypatch):
    def refuse(*args, **kwargs):  # type: ignore[no-untyped-def]
        raise AssertionError("/health connected to the broker")

    monkeypatch.setattr(mqtt.Client, "connect", refuse)
    assert Client().get("/health").status_code == 200


def test_the_checks_are_reused_for_a_few_seconds(db, linked, settings):
    first = health.cached_checks(now=1000.0)
    assert first["status"] == "ok"
    settings.REDIS_URL = "redis://127.0.0.1:1/0"
    assert health.cached_checks(now=1000.0 + settings.HEALTH_CACHE_S / 2) is first
    later = health.cached_checks(now=1000.0 + settings.HEALTH_CACHE_S)
    assert later["status"] == "error" and later["checks"]["redis"] != "ok"


def test_503_and_no_details_when_no_gateway_reports_on_the_broker(staff, broker, settings):
    settings.MQTT_URL = "mqtt://ground:x@127.0.0.1:1"
    response = Client().get("/health")
    assert response.status_code == 503
    assert response.json() == {"status": "error"}
    checks = staff.get("/health").json()["checks"]
    assert checks["database"] == "ok" and checks["redis"] == "ok"
    assert checks["broker"] == "no gateway reports on the broker at 127.0.0.1:1"


def test_a_stopped_gateway_leaves_the_broker_unreported(transactional_db, staff, linked, broker):
    assert staff.get("/health").status_code == 200
    linked.stop()
    health.forget()
    response = staff.get("/health")
    assert response.status_code == 503
    assert f"127.0.0.1:{broker.port}" in response.json()["checks"]["broker"]


def test_503_naming_redis_for_staff_when_it_is_down(staff, settings):
    settings.REDIS_URL = "redis://127.0.0.1:1/0"
    response = staff.get("/health")
    assert response.status_code == 503
    assert response.json()["checks"]["redis"] != "ok"
    assert "processes" not in response.json()
    health.forget()
    assert Client().get("/health").json() == {"status": "error"}
