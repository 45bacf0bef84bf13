from django.urls import path

from . import template_views, views

app_name = "checklists"

urlpatterns = [
    path("", template_views.templates_page, name="templates"),
    path("drones/<str:drone_id>/", views.drone_checklist, name="drone"),
]
