"""python manage.py mediaserver: the live-video relay (docs/video.md)."""

from __future__ import annotations

import asyncio
import signal

import uvicorn
from django.conf import settings

from config.service_command import ServiceCommand
from livevideo import access
from livevideo.ports import confine_udp, parse_port_range
from livevideo.relay import Relay
from livevideo.server import SharedLoopServer, drone_app, ground_app


async def serve(port: int, drone_port: int, drone_bind: str) -> None:
    recording = settings.LIVE_VIDEO_RECORD
    relay = Relay(
        access.limits(),
        recorder=access.start_recording if recording else None,
        on_recorded=access.recorded if recording else None,
    )
    servers = [
        SharedLoopServer(uvicorn.Config(ground_app(relay, access.ticket_key()), host="127.0.0.1",
                               port=port, log_level="warning", access_log=False)),
        SharedLoopServer(uvicorn.Config(drone_app(relay, access.authenticate), host=drone_bind,
                               port=drone_port, log_level="warning", access_log=False)),
    ]  # fmt: skip
    loop = asyncio.get_running_loop()
    udp_ports = parse_port_range(settings.LIVE_VIDEO_UDP_PORTS)
    if udp_ports is not None:
        confine_udp(loop, udp_ports)
    for sig in (signal.SIGTERM, signal.SIGINT):
        loop.add_signal_handler(sig, lambda: [setattr(s, "should_exit", True) for s in servers])
    tasks = [asyncio.ensure_future(s.serve()) for s in servers]
    while not all(s.started for s in servers):
        if any(t.done() for t in tasks):
            break
        await asyncio.sleep(0.05)
    print(
        f"media server ready: ground 127.0.0.1:{port}, drones {drone_bind}:{drone_port}, "
        f"media UDP {settings.LIVE_VIDEO_UDP_PORTS or 'ephemeral ports'}",
        flush=True,
    )
    try:
        await asyncio.gather(*tasks)
    finally:
        await relay.close()


class Command(ServiceCommand):
    help = "Run the live-video media server (drones publish, viewers watch through the portal)."

    def add_arguments(self, parser) -> None:  # type: ignore[no-untyped-def]
        parser.add_argument("--port", type=int, default=settings.LIVE_VIDEO_PORT)
        parser.add_argument("--drone-port", type=int, default=settings.LIVE_VIDEO_DRONE_PORT)
        parser.add_argument("--drone-bind", default=settings.LIVE_VIDEO_DRONE_BIND)

    def handle(self, *args, **options) -> None:  # type: ignore[no-untyped-def]
        asyncio.run(serve(options["port"], options["drone_port"], options["drone_bind"]))
