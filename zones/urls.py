from django.urls import path

from . import api

urlpatterns = [
    path("", api.ZoneListView.as_view(), name="zones"),
    path("<int:pk>/authorisations/", api.AuthorisationView.as_view(), name="zone-authorisations"),
]
