from django.urls import path

from alerts.consumers import AlertConsumer
from fleet.consumers import FleetConsumer
from logs.consumers import LogProgressConsumer
from missions.consumers import MissionConsumer
from pastview.consumers import PastViewConsumer
from telemetry.consumers import TelemetryConsumer

websocket_urlpatterns = [
    path("ws/fleet/", FleetConsumer.as_asgi()),
    path("ws/alerts/", AlertConsumer.as_asgi()),
    path("ws/missions/<uuid:mission_id>/", MissionConsumer.as_asgi()),
    path("ws/telemetry/<str:drone_id>/", TelemetryConsumer.as_asgi()),
    path("ws/pastview/<str:drone_id>/", PastViewConsumer.as_asgi()),
    path("ws/logs/<uuid:log_id>/", LogProgressConsumer.as_asgi()),
]
