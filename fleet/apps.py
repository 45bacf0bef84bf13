from django.apps import AppConfig


class FleetConfig(AppConfig):
    name = "fleet"
    verbose_name = "Fleet"
    default_auto_field = "django.db.models.BigAutoField"

    def ready(self) -> None:
        from .envelopes import send_when_online
        from .signals import drones_came_online

        drones_came_online.connect(send_when_online, dispatch_uid="fleet-envelope")

        from django.db.models.signals import post_save

        from .events import command_logged
        from .models import CommandLog

        post_save.connect(command_logged, sender=CommandLog, dispatch_uid="fleet-command-live")
