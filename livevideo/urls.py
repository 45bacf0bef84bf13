from django.urls import path

from . import views

app_name = "livevideo"

urlpatterns = [path("", views.wall, name="wall")]
