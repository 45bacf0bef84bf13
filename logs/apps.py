from django.apps import AppConfig


class LogsConfig(AppConfig):
    """Uploaded flight logs: the Django side of the log viewer.

    Lives inside `logs/` beside the Django-free core, as its own app (label
    `logs`) so the core package stays importable without Django.
    """

    name = "logs"
    label = "logs"
    verbose_name = "Flight logs"
    default_auto_field = "django.db.models.BigAutoField"
