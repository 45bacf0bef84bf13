from django.urls import path

from . import api

urlpatterns = [
    path("status/", api.ingest_status, name="telemetry-status"),
    path("drones/<str:drone_id>/latest/", api.latest, name="telemetry-latest"),
    path("drones/<str:drone_id>/range/", api.range_, name="telemetry-range"),
    path("drones/<str:drone_id>/export.csv", api.export, name="telemetry-export"),
]
