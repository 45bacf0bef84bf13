from django.apps import AppConfig


class ChecklistsConfig(AppConfig):
    name = "checklists"
    verbose_name = "Pre-flight checklists"
    default_auto_field = "django.db.models.BigAutoField"
