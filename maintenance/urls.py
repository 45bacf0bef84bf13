from django.urls import path

from . import views

app_name = "maintenance"

urlpatterns = [
    path("", views.fleet_due, name="due"),
    path("drones/<str:drone_id>/", views.drone_page, name="drone"),
]
