from django.urls import path

from . import views

app_name = "fleet"

urlpatterns = [
    path("", views.index, name="index"),
    path("drones/<str:drone_id>/", views.drone_detail, name="drone"),
    path("organisation/envelope/", views.envelope, name="envelope"),
    path("organisation/switch/", views.switch_organisation, name="switch_organisation"),
    path("fleet/table/", views.drone_table, name="table"),
]
