from django.urls import path

from . import views

app_name = "batteries"

urlpatterns = [
    path("", views.battery_list, name="list"),
    path("rules/", views.rules, name="rules"),
    path("drones/<str:drone_id>/choose/", views.choose, name="choose"),
]
