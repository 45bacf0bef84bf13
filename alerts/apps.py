from django.apps import AppConfig


class AlertsConfig(AppConfig):
    name = "alerts"
    default_auto_field = "django.db.models.BigAutoField"

    def ready(self) -> None:
        from . import receivers, remote_id, wind

        receivers.connect()
        remote_id.connect()
        wind.connect()
