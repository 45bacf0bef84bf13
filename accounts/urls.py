from django.urls import path

from . import views

app_name = "accounts"

urlpatterns = [
    path("security/", views.security, name="security"),
    path("security/tokens/", views.create_token, name="create_token"),
    path("security/tokens/<int:pk>/revoke/", views.revoke_token, name="revoke_token"),
    path("security/tokens/legacy/revoke/", views.revoke_legacy_token, name="revoke_legacy_token"),
]
