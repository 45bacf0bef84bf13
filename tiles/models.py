from django.db import models


class TileSet(models.Model):
    """One imported tile set; its tiles live in TILES_DIR/sets/<id>/<z>/<x>/<y>.<ext>."""

    name = models.CharField(max_length=200)
    source = models.CharField(max_length=500, blank=True, help_text="The imported file or folder.")
    attribution = models.CharField(max_length=500, blank=True)
    min_zoom = models.PositiveSmallIntegerField()
    max_zoom = models.PositiveSmallIntegerField()
    # West, south, east, north in degrees: maps ask for no tile outside them.
    west = models.FloatField()
    south = models.FloatField()
    east = models.FloatField()
    north = models.FloatField()
    tile_count = models.PositiveIntegerField()
    size_bytes = models.PositiveBigIntegerField()
    created_at = models.DateTimeField(auto_now_add=True)

    class Meta:
        ordering = ["-created_at", "-id"]

    def __str__(self) -> str:
        return f"{self.name} (z{self.min_zoom}–{self.max_zoom}, {self.tile_count} tiles)"
