from django.urls import path

from . import views

app_name = "records"

urlpatterns = [
    path("drones/<str:drone_id>/", views.drone_logbook, name="drone"),
    path("pilots/<str:username>/", views.pilot_logbook, name="pilot"),
    path("flights/<int:pk>/", views.flight_detail, name="flight"),
]
