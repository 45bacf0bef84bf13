from django.urls import path

from . import views

app_name = "telemetry"

urlpatterns = [
    path("", views.overview, name="overview"),
    path("status/", views.ingest_status, name="status"),
    path("drones/<str:drone_id>/", views.dashboard, name="dashboard"),
]
