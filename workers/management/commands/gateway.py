"""`manage.py gateway`: run the MQTT gateway until SIGTERM/SIGINT, then drain and exit."""

from __future__ import annotations

import os
import socket

from django.conf import settings

from config.service_command import ServiceCommand
from runtime.stopsignal import StopSignal
from workers.gateway import Gateway


class Command(ServiceCommand):
    help = "Bridge the drones' MQTT topics and the ground (Drone Identifier, Drone Manager)."

    def add_arguments(self, parser) -> None:  # type: ignore[no-untyped-def]
        parser.add_argument(
            "--broker",
            default=",".join(settings.MQTT_URLS),
            help="mqtt://user:pass@host:port; a cluster's nodes comma-separated, tried in turn "
            "(default MQTT_URLS)",
        )
        parser.add_argument(
            "--client-id",
            default=None,
            help="stable MQTT client id (default gateway-<host>-<instance>); its session is "
            "persistent, so messages that arrive during a restart are delivered afterwards",
        )
        parser.add_argument(
            "--instance",
            default=os.environ.get("GATEWAY_INSTANCE", "0"),
            help="distinguishes several gateways on one host (each its own session)",
        )

    def handle(self, *args, **options) -> None:  # type: ignore[no-untyped-def]
        stopping = StopSignal().install()
        client_id = options["client_id"] or f"gateway-{socket.gethostname()}-{options['instance']}"
        gateway = Gateway(options["broker"], client_id=client_id, persistent=True)
        gateway.start()
        inbound = "AMQP queue skyhive.gateway" if gateway.consumer is not None else "MQTT"
        self.stdout.write(f"gateway: {gateway.host}:{gateway.port} ({inbound})", ending="\n")
        self.stdout.flush()
        while not stopping.wait(1.0):
            gateway.counters.flush()
        gateway.stop()
        self.stdout.write("gateway: stopped")
