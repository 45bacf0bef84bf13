from django.apps import AppConfig


class TilesConfig(AppConfig):
    """Map tiles served by the portal itself: imported tile sets and an optional
    pass-through cache of an online source, so maps work in a field without internet."""

    name = "tiles"
    verbose_name = "Map tiles"
    default_auto_field = "django.db.models.BigAutoField"
