from django.apps import AppConfig
from django.contrib.admin import apps as admin_apps


class AccountsConfig(AppConfig):
    name = "accounts"
    default_auto_field = "django.db.models.BigAutoField"

    def ready(self) -> None:
        from . import receivers

        receivers.connect()


class AdminConfig(admin_apps.AdminConfig):
    """`django.contrib.admin` on the site of accounts/admin_site.py: the portal's sign-in
    and second factor (named in INSTALLED_APPS in place of `django.contrib.admin`)."""

    default = False  # "accounts" alone still means AccountsConfig
    default_site = "accounts.admin_site.AdminSite"
