from django.core.validators import MaxValueValidator, MinValueValidator
from django.db import models


class TerrainTile(models.Model):
    """One imported elevation grid; its samples live in TERRAIN_DIR/tiles/<id>.npy.

    The bounds are those of the sample centres, where the elevation can be interpolated;
    the cell sizes are the spacing between samples.
    """

    name = models.CharField(max_length=200, help_text="The file the grid came from.")
    source = models.CharField(max_length=500, blank=True, help_text="The imported path.")
    kind = models.CharField(max_length=10, help_text="hgt (SRTM) or geotiff.")
    west = models.FloatField()
    south = models.FloatField()
    east = models.FloatField()
    north = models.FloatField()
    rows = models.PositiveIntegerField()
    cols = models.PositiveIntegerField()
    cell_lat = models.FloatField(help_text="Degrees of latitude between samples.")
    cell_lon = models.FloatField(help_text="Degrees of longitude between samples.")
    void_count = models.PositiveBigIntegerField(help_text="Samples without an elevation.")
    created_at = models.DateTimeField(auto_now_add=True)

    class Meta:
        ordering = ["-created_at", "-id"]
        indexes = [models.Index(fields=["south", "north", "west", "east"])]

    def __str__(self) -> str:
        return f"{self.name} ({self.south:g}..{self.north:g}, {self.west:g}..{self.east:g})"

    @property
    def resolution_arcsec(self) -> float:
        return round(self.cell_lat * 3600.0, 3)


class TerrainClearance(models.Model):
    """An organisation's minimum terrain clearance (TERRAIN_MIN_CLEARANCE when it has none)."""

    organisation = models.OneToOneField(
        "fleet.Organisation", on_delete=models.CASCADE, related_name="terrain_clearance"
    )
    min_clearance = models.FloatField(
        validators=[MinValueValidator(0.0), MaxValueValidator(10_000.0)],
        help_text="Metres every leg keeps above the terrain.",
    )
    ceiling_above_terrain = models.BooleanField(
        default=False,
        help_text=(
            "Also read the envelope's maximum height above the terrain wherever it is "
            "imported (the maximum above home still holds)."
        ),
    )

    def __str__(self) -> str:
        return f"{self.organisation}: {self.min_clearance:g} m"
