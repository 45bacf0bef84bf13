from django.apps import AppConfig


class MissionsConfig(AppConfig):
    name = "missions"
    verbose_name = "Missions"
    default_auto_field = "django.db.models.BigAutoField"

    def ready(self) -> None:
        from django.db.models.signals import post_save

        from fleet.models import ConnectionEvent

        from .signals import drone_came_online

        post_save.connect(drone_came_online, sender=ConnectionEvent, dispatch_uid="missions-resume")
