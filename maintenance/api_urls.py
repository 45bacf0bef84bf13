"""The maintenance API's routes, under /api/v1/ (maintenance/api.py)."""

from django.urls import path, re_path

from . import api

DRONE = r"^drones/(?P<drone_id>[A-Za-z0-9_-]{1,64})/maintenance/"

urlpatterns = [
    path(
        "organisations/<slug:slug>/maintenance/schedules/",
        api.SchedulesView.as_view(),
        name="maintenance-schedules",
    ),
    path(
        "maintenance/schedules/<int:pk>/",
        api.ScheduleView.as_view(),
        name="maintenance-schedule",
    ),
    path(
        "organisations/<slug:slug>/maintenance/bulletins/",
        api.BulletinsView.as_view(),
        name="maintenance-bulletins",
    ),
    path(
        "organisations/<slug:slug>/maintenance/due/",
        api.DueView.as_view(),
        name="maintenance-due",
    ),
    re_path(DRONE + r"$", api.DroneItemsView.as_view(), name="drone-maintenance"),
    re_path(DRONE + r"log/$", api.DroneLogView.as_view(), name="drone-maintenance-log"),
]
