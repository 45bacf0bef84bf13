"""A ground of a benchmark's own: a test database, a private Mosquitto the settings point
at, an operator with provisioned drones, and the real ground processes on them."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from runtime.processes import Supervised, free_port, python_env
from workers.ground import web_argv


def database_and_broker(folder: Path, ground_password: str) -> tuple[str, Any]:
    """A fresh test database and a Mosquitto in `folder`, with this process's settings
    (and so the drones' credentials it provisions) pointing at them."""
    from django.conf import settings
    from django.db import connection

    from workers import outbox
    from workers.mosquitto import start_broker

    db_name = connection.creation.create_test_db(verbosity=0, autoclobber=True, keepdb=False)
    broker = start_broker(
        folder / "mosquitto",
        {"ground": ground_password},
        extra_config=f"pid_file {folder / 'mosquitto' / 'mosquitto.pid'}\n",
    )
    settings.MOSQUITTO_DIR = str(broker.directory)
    settings.MQTT_URL = broker.url_for("ground")
    settings.MQTT_PUBLIC_HOST, settings.MQTT_PUBLIC_PORT = "127.0.0.1", broker.port
    outbox.sync_redis().delete(outbox.outbox_key())
    return db_name, broker


def operator_and_drones(names: list[str]) -> tuple[Any, str, dict[str, str]]:
    """An operator of a new organisation (the user and a personal API token, as
    `POST /api/v1/token/` gives) and each drone's broker password."""
    from django.contrib.auth import get_user_model

    from accounts import tokens
    from fleet import credentials
    from fleet.models import Membership, Organisation, Role

    organisation = Organisation.objects.create(name="Bench", slug="bench")
    user = get_user_model().objects.create_user("bench-operator", password="x")
    Membership.objects.create(user=user, organisation=organisation, role=Role.OPERATOR)
    passwords = {name: credentials.provision(name, "bench").password for name in names}
    return user, tokens.issue(user, name="bench").key, passwords


def ground_env(db_name: str, broker: Any) -> dict[str, str]:
    """The environment of a ground process on that database and broker."""
    return python_env(
        TEST_WORKER_DB_NAME=db_name,
        MQTT_URL=broker.url_for("ground"),
        MOSQUITTO_DIR=str(broker.directory),
        PYTHONUNBUFFERED="1",
        LOG_LEVEL="WARNING",
    )


def start_web(env: dict[str, str], ready_timeout: float) -> Supervised:
    """The ASGI app under uvicorn, as `make run` serves it; returned once it answers."""
    port = free_port()
    web = Supervised("web", [*web_argv(port), "--log-level", "warning"], env, port=port)
    web.start()
    web.wait_ready(ready_timeout)
    return web
