from django.contrib.auth import views as auth_views
from django.urls import path

from . import audit_views, member_views, signin, views

app_name = "accounts"

urlpatterns = [
    path("security/", views.security, name="security"),
    path("security/tokens/", views.create_token, name="create_token"),
    path("security/tokens/<int:pk>/revoke/", views.revoke_token, name="revoke_token"),
    path("security/tokens/legacy/revoke/", views.revoke_legacy_token, name="revoke_legacy_token"),
]

urlpatterns += [
    path("members/", member_views.members_page, name="members"),
    path("members/invite/", member_views.invite, name="invite"),
    path("members/<int:pk>/role/", member_views.change_role, name="change_role"),
    path("members/<int:pk>/remove/", member_views.remove_member, name="remove_member"),
    path(
        "invitations/<int:pk>/revoke/",
        member_views.revoke_invitation,
        name="revoke_invitation",
    ),
    path("invitation/<str:key>/", member_views.invitation, name="invitation"),
]

urlpatterns += [
    path("audit/", audit_views.audit_page, name="audit"),
    path("audit.csv", audit_views.audit_csv, name="audit_csv"),
]

urlpatterns += [
    path("login/code/", signin.login_code, name="login_code"),
    path("security/two-factor/", views.two_factor, name="two_factor"),
    path("security/two-factor/disable/", views.disable_two_factor, name="disable_two_factor"),
    path("password/reset/", views.PasswordResetView.as_view(), name="password_reset"),
    path(
        "password/reset/sent/",
        auth_views.PasswordResetDoneView.as_view(),
        name="password_reset_done",
    ),
    path(
        "password/reset/<uidb64>/<token>/",
        views.PasswordResetConfirmView.as_view(),
        name="password_reset_confirm",
    ),
    path(
        "password/reset/done/",
        auth_views.PasswordResetCompleteView.as_view(),
        name="password_reset_complete",
    ),
]

urlpatterns += [
    path("organisation/", member_views.organisation_settings, name="organisation"),
]
