"""End-to-end harness: a private Mosquitto, the real gateway, a real Celery worker and
simulated drones (firmware.sim.fleet: firmware.sim and the onboard agent per drone,
speaking UAVTalk or MAVLink), on the test database.

Other suites may run against the same Redis at the same time, so the gateway
outbox lives in a Redis database of our own and our Celery tasks go to a queue of our
own; neither changes what is tested.
"""

from __future__ import annotations

import threading
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from django.conf import settings

from firmware.sim.fleet import Drone, start_drone
from runtime.processes import wait_for
from tests.support.celery_worker import consuming_worker, worker_env
from workers.mosquitto import Broker, start_broker

from .conftest import AVEIRO, OUTBOX_DB, point_at, redis_url_with_db

GROUND_PASSWORD = "ground-e2e-password"
# Simulated seconds per real second: a five-minute survey takes about 15 s.
TIME_SCALE = 20.0
HOME_ALT_MSL = 12.0
BEAT_INTERVAL_S = 1.0


class Worker:
    """`celery worker` on the test database, consuming our own queue only."""

    def __init__(self, database_name: str, log_dir: Path, broker_url: str) -> None:
        from config.celery import app

        self.queue = f"missions-e2e-{uuid.uuid4().hex[:8]}"
        self._previous_queue = app.conf.task_default_queue
        app.conf.task_default_queue = self.queue
        env = worker_env(
            database_name,
            REDIS_URL=redis_url_with_db(settings.REDIS_URL, OUTBOX_DB),
            # The outbox is per broker: the worker must queue for the test's broker.
            MQTT_URL=broker_url,
            CELERY_BROKER_URL=str(app.conf.broker_url),
            CELERY_RESULT_BACKEND=str(app.conf.result_backend),
            PYTHONUNBUFFERED="1",
        )
        env.pop("DJANGO_ALLOW_ASYNC_UNSAFE", None)
        log_path = log_dir / f"worker-{self.queue}.log"
        self.process = consuming_worker(self.queue, env, log_path, queue=self.queue)

    def stop(self) -> None:
        from config.celery import app

        self.process.stop()
        app.conf.task_default_queue = self._previous_queue


class Ground:
    """The module's private broker, the settings pointing at it, and the Celery worker."""

    def __init__(self, directory: Path, database_name: str) -> None:
        from workers import outbox

        self.directory = directory
        mosquitto = directory / "mosquitto"
        self.broker = start_broker(
            mosquitto,
            {"ground": GROUND_PASSWORD},
            extra_config=f"pid_file {mosquitto / 'mosquitto.pid'}\n",
        )
        self._saved: dict[str, Any] = {}
        overrides = {
            "MOSQUITTO_DIR": str(mosquitto),
            "MQTT_URL": self.broker.url_for("ground"),
            "MQTT_PUBLIC_HOST": "127.0.0.1",
            "MQTT_PUBLIC_PORT": self.broker.port,
            "REDIS_URL": redis_url_with_db(settings.REDIS_URL, OUTBOX_DB),
        }
        for name, value in overrides.items():
            self._saved[name] = getattr(settings, name)
            setattr(settings, name, value)
        outbox._sync_client = None
        self.worker = Worker(database_name, directory, self.broker.url_for("ground"))
        self._beating = threading.Event()
        self._beat = threading.Thread(target=self._beat_loop, daemon=True)
        self._beat.start()

    def _beat_loop(self) -> None:
        """Stands in for Celery beat, which sends missions.resume_paused every
        MISSIONS_RESUME_INTERVAL_S in production, to our own queue (a real beat would
        also send other apps' periodic tasks to the shared one)."""
        from missions import tasks

        while not self._beating.wait(BEAT_INTERVAL_S):
            tasks.resume_paused.delay()

    def close(self) -> None:
        from workers import outbox

        self._beating.set()
        self._beat.join()
        self.worker.stop()
        self.broker.stop()
        for name, value in self._saved.items():
            setattr(settings, name, value)
        outbox._sync_client = None


@dataclass
class Sky:
    """One test's gateway and drones, on the module's broker and worker."""

    tmp_path: Path
    organisation_slug: str
    ground: Ground
    time_scale: float = TIME_SCALE
    gateway: Any = None
    drones: list[Drone] = field(default_factory=list)

    @property
    def broker(self) -> Broker:
        return self.ground.broker

    def start(self) -> Sky:
        from workers import outbox

        outbox.sync_redis().delete(outbox.outbox_key())
        self.start_gateway()
        return self

    def start_gateway(self) -> None:
        from workers.counters import Counters
        from workers.gateway import Gateway

        # One identity per broker, as `manage.py gateway` has one per host: the broker
        # keeps its session and queues what arrives while it is down. Per broker, not per
        # test, or a finished test's session would keep its share of the subscriptions.
        tag = f"{self.broker.port}"  # type: ignore[union-attr]
        self.gateway = Gateway(
            self.broker.url_for("ground"),  # type: ignore[union-attr]
            client_id=f"gw-missions-{tag}",
            persistent=True,
            counters=Counters(f"gateway-missions-{tag}", flush_every=1e9),
        )
        self.gateway.start()
        assert self.gateway.wait_connected(10), "the gateway did not connect"

    def stop_gateway(self) -> None:
        self.gateway.stop()

    def add_drone(
        self,
        drone_id: str,
        *,
        north: float = 0.0,
        east: float = 0.0,
        extra: list[str] = (),  # type: ignore[assignment]
        fc: str = "uavtalk",
        **sim_options: Any,
    ) -> Drone:
        """Provision the drone and start its simulator (`sim_options` for start_simulator,
        e.g. battery_capacity_mah) and agent, speaking `fc`; wait_online() waits for it."""
        from fleet import credentials

        creds = credentials.provision(drone_id, self.organisation_slug)
        lat, lon = point_at(north, east)
        url = f"mqtt://{drone_id}:{creds.password}@127.0.0.1:{self.broker.port}"  # type: ignore[union-attr]
        drone = start_drone(
            self.tmp_path / drone_id,
            drone_id,
            url,
            (lat, lon, HOME_ALT_MSL),
            time_scale=self.time_scale,
            fc=fc,
            agent_args=["--heartbeat-interval", "0.3", *extra],
            **sim_options,
        )
        self.drones.append(drone)
        return drone

    def wait_online(self, timeout: float = 30.0) -> None:
        from fleet.models import Drone

        ids = [d.drone_id for d in self.drones]

        def ready() -> bool:
            rows = Drone.objects.filter(drone_id__in=ids, online=True, lat__isnull=False)
            return rows.exclude(battery_remaining__isnull=True).count() == len(ids)

        assert wait_for(ready, timeout), f"drones not online: {self.describe()}"

    def describe(self) -> str:
        from fleet.models import Drone

        rows = Drone.objects.filter(drone_id__in=[d.drone_id for d in self.drones])
        return ", ".join(
            f"{d.drone_id}(online={d.online}, pos={d.lat},{d.lon}, batt={d.battery_remaining})"
            for d in rows
        )

    def close(self) -> None:
        for drone in self.drones:
            drone.stop()
        if self.gateway is not None:
            self.gateway.stop()


def metres(a: tuple[float, float], b: tuple[float, float]) -> float:
    import math

    n, e = AVEIRO.to_ne([a[0], b[0]], [a[1], b[1]])
    return math.hypot(float(n[1] - n[0]), float(e[1] - e[0]))
