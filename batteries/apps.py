from django.apps import AppConfig


class BatteriesConfig(AppConfig):
    name = "batteries"
    verbose_name = "Batteries"
    default_auto_field = "django.db.models.BigAutoField"
