from django.apps import AppConfig


class AirspaceConfig(AppConfig):
    name = "airspace"
    verbose_name = "Airspace"
    default_auto_field = "django.db.models.BigAutoField"

    def ready(self) -> None:
        from django.db.models.signals import post_save

        from .reservations import reserve_when_assigned

        # A lazy sender: airspace sits below missions and never imports it.
        post_save.connect(
            reserve_when_assigned, sender="missions.Assignment", dispatch_uid="airspace-reserve"
        )
