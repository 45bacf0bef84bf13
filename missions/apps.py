from django.apps import AppConfig


class MissionsConfig(AppConfig):
    name = "missions"
    verbose_name = "Missions"
    default_auto_field = "django.db.models.BigAutoField"

    def ready(self) -> None:
        from fleet.signals import drones_came_online, drones_went_offline

        from .signals import replace_when_drones_go_offline, resume_when_drones_come_online

        drones_came_online.connect(resume_when_drones_come_online, dispatch_uid="missions-resume")
        drones_went_offline.connect(replace_when_drones_go_offline, dispatch_uid="missions-offline")

        from .eventlog import drones_offline, drones_online

        drones_came_online.connect(drones_online, dispatch_uid="missions-eventlog-online")
        drones_went_offline.connect(drones_offline, dispatch_uid="missions-eventlog-offline")
