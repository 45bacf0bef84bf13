from django.urls import path

from fleet.consumers import FleetConsumer
from telemetry.consumers import TelemetryConsumer

websocket_urlpatterns = [
    path("ws/fleet/", FleetConsumer.as_asgi()),
    path("ws/telemetry/<str:drone_id>/", TelemetryConsumer.as_asgi()),
]
