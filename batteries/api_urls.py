from django.urls import path, re_path
from rest_framework.routers import SimpleRouter

from . import api

router = SimpleRouter()
router.register("batteries", api.BatteryViewSet, basename="battery")

urlpatterns = [
    re_path(
        r"^drones/(?P<drone_id>[A-Za-z0-9_-]{1,64})/battery/$",
        api.DroneBatteryView.as_view(),
        name="drone-battery",
    ),
    path(
        "organisations/<slug:slug>/battery-policy/",
        api.BatteryPolicyView.as_view(),
        name="organisation-battery-policy",
    ),
    *router.urls,
]
