from django.apps import AppConfig


class PastViewConfig(AppConfig):
    """The past-image view as an app: its settings model and `manage.py pastview`."""

    name = "pastview"
    label = "pastview"
    verbose_name = "Past-image view"
    default_auto_field = "django.db.models.BigAutoField"
