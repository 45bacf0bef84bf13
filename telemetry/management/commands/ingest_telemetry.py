"""`manage.py ingest_telemetry`: the broker-to-database connector (run several in parallel).

Drains on SIGTERM/SIGINT: stops reading, writes what it holds, then exits.
"""

from __future__ import annotations

import logging
import signal
import subprocess
import sys

from django.conf import settings

from config.service_command import ServiceCommand
from runtime.stopsignal import StopSignal
from telemetry.ingest import (
    SHARE_GROUP,
    DroneMap,
    IngestConfig,
    Ingestor,
    Limits,
    load_drone_ids,
)
from telemetry.live import ChannelsLivePublisher
from telemetry.queries import conninfo_from_settings
from workers import broker
from workers.counters import Counters

log = logging.getLogger(__name__)


class Command(ServiceCommand):
    help = "Store every drone's telemetry from the broker into PostgreSQL (COPY batches)."

    def add_arguments(self, parser) -> None:  # type: ignore[no-untyped-def]
        parser.add_argument("--mqtt-url", default=None, help="Broker URL (default MQTT_URL).")
        parser.add_argument(
            "--database-url", default=None, help="Store into this database instead."
        )
        parser.add_argument("--no-live", action="store_true", help="Do not push live values.")
        parser.add_argument("--drain-timeout", type=float, default=30.0)
        parser.add_argument(
            "--processes",
            type=int,
            default=1,
            help="Run this many ingest processes sharing the subscription (one per core).",
        )

    def handle(self, *args, **options) -> None:  # type: ignore[no-untyped-def]
        if options["processes"] > 1:
            self._supervise(options["processes"])
            return
        conninfo = options["database_url"] or conninfo_from_settings()
        config = IngestConfig(
            conninfo=conninfo,
            mqtt_url=options["mqtt_url"] or settings.MQTT_URL,
            flush_rows=settings.TELEMETRY_FLUSH_ROWS,
            flush_interval=settings.TELEMETRY_FLUSH_INTERVAL_S,
            buffer_rows=settings.TELEMETRY_BUFFER_ROWS,
            limits=Limits(
                max_bytes=settings.TELEMETRY_MAX_MESSAGE_BYTES,
                max_past_s=settings.TELEMETRY_MAX_PAST_S,
                max_future_s=settings.TELEMETRY_MAX_FUTURE_S,
            ),
            live_hz=settings.TELEMETRY_LIVE_HZ,
            # An explicit --mqtt-url means that broker, over MQTT.
            amqp_urls=broker.amqp_urls() if broker.uses_amqp() and not options["mqtt_url"] else [],
        )
        ingestor = Ingestor(
            config,
            drones=DroneMap(lambda: load_drone_ids(conninfo)),
            counters=Counters("ingest"),
            live=None if options["no_live"] else ChannelsLivePublisher(),
        )
        stopping = StopSignal().install()
        ingestor.start()
        source = (
            f"AMQP queue skyhive.{SHARE_GROUP}"
            if config.amqp_urls
            else config.mqtt_url.split("@")[-1]
        )
        self.stdout.write(f"ingest_telemetry: reading {source}")
        self.stdout.flush()
        while not stopping.wait(0.2):
            pass
        drained = ingestor.stop(drain_timeout=options["drain_timeout"])
        self.stdout.write(
            f"ingest_telemetry: stopped, {ingestor.stored} objects stored"
            + ("" if drained else ", buffer NOT fully written")
        )

    def _supervise(self, count: int) -> None:
        """Start `count` single-process ingests; forward SIGTERM/SIGINT; wait for all.

        One reader tops out near 10 000 messages/s on one core; the broker spreads the
        messages over the processes (Mosquitto's shared subscription, or RabbitMQ's shared
        queue skyhive.ingest).
        """
        argv = [a for a in sys.argv if not a.startswith("--processes")]
        if "--processes" in sys.argv:
            index = sys.argv.index("--processes")
            argv = sys.argv[:index] + sys.argv[index + 2 :]
        children = [subprocess.Popen([sys.executable, *argv]) for _ in range(count)]

        def forward(signum: int, frame: object) -> None:
            for child in children:
                if child.poll() is None:
                    child.send_signal(signum)

        for sig in (signal.SIGTERM, signal.SIGINT):
            signal.signal(sig, forward)
        codes = [child.wait() for child in children]
        if any(codes):
            raise SystemExit(max(codes))
