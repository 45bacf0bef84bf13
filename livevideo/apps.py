from django.apps import AppConfig


class LiveVideoConfig(AppConfig):
    name = "livevideo"
    verbose_name = "Live video"
