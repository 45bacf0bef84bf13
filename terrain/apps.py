from django.apps import AppConfig


class TerrainConfig(AppConfig):
    """Elevation data imported offline (SRTM .hgt, GeoTIFF DEMs), the elevation lookup and
    the minimum terrain clearance the flight envelope holds every leg to."""

    name = "terrain"
    verbose_name = "Terrain"
    default_auto_field = "django.db.models.BigAutoField"
