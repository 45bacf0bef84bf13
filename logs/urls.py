from django.urls import path
from rest_framework.routers import SimpleRouter

from logs import policy_views, trend_views, views
from logs.api import FlightLogViewSet
from logs.collect_api import CollectChunkView, CollectOfferView
from logs.policy_api import DroneLogCollectionView
from logs.trends_api import DroneTrend, FleetTrend

app_name = "logs"

# The portal pages, included at /logs/ (namespace "logs").
urlpatterns = [
    path("", views.log_list, name="list"),
    path("compare/", views.log_compare, name="compare"),
    path("compare/overlay/", trend_views.overlay, name="overlay"),
    path("trends/", trend_views.fleet_trends, name="trends"),
    path("trends/<str:drone_id>/", trend_views.drone_trends, name="drone_trends"),
    path("collection/<str:drone_id>/", policy_views.set_collection, name="collection"),
    path("<uuid:pk>/", views.log_detail, name="detail"),
    path("<uuid:pk>/download/", views.log_download, name="download"),
]

# The REST resources, included at /api/v1/logs/.
_router = SimpleRouter()
_router.register("", FlightLogViewSet, basename="flightlog")
# The drones' own uploads after landing (logs/collection.py), before the router's ids.
api_urlpatterns = [
    path("collect/", CollectOfferView.as_view(), name="collect"),
    path("collect/<uuid:upload_id>/", CollectChunkView.as_view(), name="collect-chunk"),
    path(
        "collection/<str:drone_id>/",
        DroneLogCollectionView.as_view(),
        name="drone-log-collection",
    ),
    path("trends/", FleetTrend.as_view(), name="log-trends"),
    path("trends/drones/<str:drone_id>/", DroneTrend.as_view(), name="log-drone-trends"),
    *_router.urls,
]
