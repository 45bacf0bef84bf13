"""`manage.py pastview`: run the past-image view service until SIGTERM/SIGINT."""

from __future__ import annotations

from django.conf import settings

from config.service_command import ServiceCommand
from pastview.runner import PastViewProcess
from runtime.stopsignal import StopSignal


class Command(ServiceCommand):
    help = "Select past camera frames for every drone pose and push them to the past-view pages."

    def add_arguments(self, parser) -> None:  # type: ignore[no-untyped-def]
        parser.add_argument(
            "--broker", default=settings.MQTT_URL, help="mqtt://user:pass@host:port"
        )
        parser.add_argument("--client-id", default=None)

    def handle(self, *args, **options) -> None:  # type: ignore[no-untyped-def]
        stopping = StopSignal().install()
        process = PastViewProcess(options["broker"], client_id=options["client_id"])
        self.stdout.write(f"pastview: {process.address}")
        self.stdout.flush()
        process.run(stopping)
        self.stdout.write("pastview: stopped")
