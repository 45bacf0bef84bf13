from django.urls import path

from . import views

app_name = "missions"

urlpatterns = [
    path("", views.mission_list, name="list"),
    path("plan/", views.planner, name="planner"),
    path("log-viewer/", views.log_viewer, name="log-viewer"),
    path("panic/", views.panic_page, name="panic"),
    path("pictures/<int:pk>/", views.picture, name="picture"),
    path("pictures/<int:pk>/thumbnail/", views.picture_thumbnail, name="picture-thumbnail"),
    path("<uuid:pk>/", views.mission_detail, name="detail"),
]
