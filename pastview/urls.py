from django.urls import path

from . import api, views

app_name = "pastview"

urlpatterns = [
    path("api/<str:drone_id>/settings/", api.view_settings, name="settings"),
    path("<str:drone_id>/", views.page, name="page"),
]
