from django.urls import path
from rest_framework.routers import SimpleRouter

from logs import views
from logs.api import FlightLogViewSet

app_name = "logs"

# The portal pages, included at /logs/ (namespace "logs").
urlpatterns = [
    path("", views.log_list, name="list"),
    path("compare/", views.log_compare, name="compare"),
    path("<uuid:pk>/", views.log_detail, name="detail"),
    path("<uuid:pk>/download/", views.log_download, name="download"),
]

# The REST resources, included at /api/v1/logs/.
_router = SimpleRouter()
_router.register("", FlightLogViewSet, basename="flightlog")
api_urlpatterns = _router.urls
