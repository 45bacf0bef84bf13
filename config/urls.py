from django.contrib import admin
from django.contrib.auth import views as auth_views
from django.http import HttpRequest, HttpResponsePermanentRedirect
from django.templatetags.static import static
from django.urls import include, path, re_path
from drf_spectacular.views import (
    SpectacularAPIView,
    SpectacularRedocView,
    SpectacularSwaggerSplitView,
)
from rest_framework.routers import DefaultRouter

from accounts import api as accounts_api
from accounts import schema as _schema  # noqa: F401 - registers the session scheme
from accounts.signin import LoginView
from airspace import api as airspace_api
from alerts import api as alerts_api
from checklists import api as checklists_api
from fleet import api as fleet_api
from fleet import remote_id_api
from fleet.control import ControlView
from logs import urls as logs_urls
from missions import api as missions_api
from missions import survey_api
from records import api as records_api
from telemetry import views as operations_views

from .health import health


def favicon(request: HttpRequest) -> HttpResponsePermanentRedirect:
    return HttpResponsePermanentRedirect(static("favicon.svg"))


router = DefaultRouter()
router.register("drones", fleet_api.DroneViewSet, basename="drone")
router.register("missions", missions_api.MissionViewSet, basename="mission")
router.register("flights", records_api.FlightViewSet, basename="flight")

api_v1 = [
    path("me/", fleet_api.me, name="me"),
    path("token/", accounts_api.obtain_token, name="token"),
    path("tokens/", accounts_api.my_tokens, name="tokens"),
    path("tokens/<int:pk>/", accounts_api.revoke_my_token, name="token-revoke"),
    re_path(
        r"^drones/(?P<drone_id>[A-Za-z0-9_-]{1,64})/commands/$",
        fleet_api.DroneCommandView.as_view(),
        name="drone-commands",
    ),
    path(
        "organisations/<slug:slug>/envelope/",
        fleet_api.EnvelopeView.as_view(),
        name="organisation-envelope",
    ),
    re_path(
        r"^drones/(?P<drone_id>[A-Za-z0-9_-]{1,64})/identity/$",
        remote_id_api.DroneIdentityView.as_view(),
        name="drone-identity",
    ),
    re_path(
        r"^drones/(?P<drone_id>[A-Za-z0-9_-]{1,64})/airworthiness/$",
        remote_id_api.AirworthinessView.as_view(),
        name="drone-airworthiness",
    ),
    path(
        "organisations/<slug:slug>/remote-id/",
        remote_id_api.OrganisationRemoteIdView.as_view(),
        name="organisation-remote-id",
    ),
    re_path(
        r"^drones/(?P<drone_id>[A-Za-z0-9_-]{1,64})/checklists/$",
        checklists_api.DroneChecklistsView.as_view(),
        name="drone-checklists",
    ),
    path(
        "organisations/<slug:slug>/checklists/",
        checklists_api.TemplatesView.as_view(),
        name="organisation-checklists",
    ),
    path(
        "organisations/<slug:slug>/checklists/<int:pk>/",
        checklists_api.TemplateView.as_view(),
        name="organisation-checklist",
    ),
    path(
        "organisations/<slug:slug>/checklist-rule/",
        checklists_api.RuleView.as_view(),
        name="organisation-checklist-rule",
    ),
    path(
        "organisations/<slug:slug>/envelope/plan/",
        fleet_api.envelope_plan,
        name="organisation-envelope-plan",
    ),
    path(
        "organisations/<slug:slug>/reservations/",
        airspace_api.ReservationsView.as_view(),
        name="organisation-reservations",
    ),
    path("telemetry/", include("telemetry.api_urls")),
    path("logs/", include(logs_urls.api_urlpatterns)),
    path("operations/", operations_views.operations_api, name="operations"),
    path("missions/survey/", survey_api.plan, name="mission-survey"),
    path("missions/survey/cameras/", survey_api.cameras, name="mission-survey-cameras"),
    path("alerts/", alerts_api.recent, name="alerts"),
    path("zones/", include("zones.urls")),
    path("", include("maintenance.api_urls")),
    path("", include("livevideo.api_urls")),
    path("", include("batteries.api_urls")),
    path("", include(router.urls)),
]

urlpatterns = [
    path("health", health, name="health"),
    path("control", ControlView.as_view(), name="control"),
    path("admin/", admin.site.urls),
    path("accounts/login/", LoginView.as_view(), name="login"),
    path("accounts/logout/", auth_views.LogoutView.as_view(), name="logout"),
    path(
        "accounts/password/",
        auth_views.PasswordChangeView.as_view(),
        name="password_change",
    ),
    path(
        "accounts/password/done/",
        auth_views.PasswordChangeDoneView.as_view(),
        name="password_change_done",
    ),
    path("accounts/", include("accounts.urls")),
    path("api/v1/", include((api_v1, "api"), namespace="api")),
    path("api/schema/", SpectacularAPIView.as_view(), name="schema"),
    # The split view serves Swagger UI's start script as a file: no inline script (CSP).
    path("api/docs/", SpectacularSwaggerSplitView.as_view(url_name="schema"), name="api-docs"),
    path(
        "api/redoc/",
        SpectacularRedocView.as_view(url_name="schema", template_name="api/redoc.html"),
        name="api-redoc",
    ),
    # Browsers ask for /favicon.ico on pages without an icon link (the admin's).
    path("favicon.ico", favicon),
    path("tiles/", include("tiles.urls")),
    path("missions/", include("missions.urls")),
    path("telemetry/", include("telemetry.urls")),
    path("pastview/", include("pastview.urls")),
    path("video/", include("livevideo.urls")),
    path("logs/", include("logs.urls")),
    path("records/", include("records.urls")),
    path("maintenance/", include("maintenance.urls")),
    path("batteries/", include("batteries.urls")),
    path("checklists/", include("checklists.urls")),
    path("operations/", operations_views.operations_page, name="operations"),
    path("", include("fleet.urls")),
]
