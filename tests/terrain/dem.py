"""Synthetic elevation models written as their publishers write them.

A 1° SRTM tile (N40W009, around Aveiro) of flat ground 10 m above sea level with a
smooth 200 m hill whose top is a sample 600 m north of home, written byte-exact to the
SRTM format (big-endian int16, rows from north to south, -32768 for voids), and the same
ground as a GeoTIFF with tifffile's writer and the GeoTIFF 1.1 tags.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import tifffile

from onboard.envelope import ned_to_latlon

HOME = (40.6303, -8.6575)
TILE = (40, -9)  # the lower-left corner: N40W009
GROUND = 10.0
HILL = 200.0
HILL_RADIUS = 450.0
HILL_NORTH = 600.0  # metres north of home, rounded to the nearest sample
SRTM_VOID = -32768


@dataclass
class Dem:
    """Samples (int16, row 0 at the north) and where they lie."""

    samples: np.ndarray
    north: float  # latitude of row 0's samples
    west: float  # longitude of column 0's samples
    step: float  # degrees between samples

    def sample_at(self, lat: float, lon: float) -> tuple[int, int]:
        return round((self.north - lat) / self.step), round((lon - self.west) / self.step)

    def latlon(self, row: int, col: int) -> tuple[float, float]:
        return self.north - row * self.step, self.west + col * self.step

    def bilinear(self, lat: float, lon: float) -> float:
        fr, fc = (self.north - lat) / self.step, (lon - self.west) / self.step
        r, c = int(math.floor(fr)), int(math.floor(fc))
        t, u = fr - r, fc - c
        s = self.samples.astype(float)
        top = s[r, c] * (1 - u) + s[r, c + 1] * u
        bottom = s[r + 1, c] * (1 - u) + s[r + 1, c + 1] * u
        return top * (1 - t) + bottom * t

    def hill_top(self) -> tuple[float, float]:
        row, col = np.unravel_index(int(np.argmax(self.samples)), self.samples.shape)
        return self.latlon(int(row), int(col))


def hill_tile(side: int = 1201) -> Dem:
    """The N40W009 tile at 3 (1201) or 1 (3601) arc-seconds with the hill on it."""
    step = 1.0 / (side - 1)
    dem = Dem(np.zeros((side, side), dtype=np.int16), TILE[0] + 1.0, float(TILE[1]), step)
    top = dem.latlon(*dem.sample_at(*ned_to_latlon(HILL_NORTH, 0.0, HOME)))
    rows = dem.north - np.arange(side) * step
    cols = dem.west + np.arange(side) * step
    north = (rows - top[0])[:, None] * 111_319.49
    east = (cols - top[1])[None, :] * 111_319.49 * math.cos(math.radians(top[0]))
    r = np.hypot(north, east)
    bump = np.where(r < HILL_RADIUS, np.cos(np.pi / 2 * r / HILL_RADIUS) ** 2, 0.0)
    dem.samples[:] = np.round(GROUND + HILL * bump).astype(np.int16)
    return dem


def with_void(dem: Dem, lat: float, lon: float, half: int = 2) -> Dem:
    """The same ground with a square of voids around (lat, lon)."""
    row, col = dem.sample_at(lat, lon)
    samples = dem.samples.copy()
    samples[row - half : row + half + 1, col - half : col + half + 1] = SRTM_VOID
    return Dem(samples, dem.north, dem.west, dem.step)


def hgt_name(dem: Dem) -> str:
    lat, lon = round(dem.north - (dem.samples.shape[0] - 1) * dem.step), round(dem.west)
    return f"{'N' if lat >= 0 else 'S'}{abs(lat):02d}{'E' if lon >= 0 else 'W'}{abs(lon):03d}.hgt"


def write_hgt(folder: Path, dem: Dem, name: str | None = None) -> Path:
    """SRTM: big-endian signed 16-bit samples, row by row from the north, nothing else."""
    path = folder / (name or hgt_name(dem))
    path.write_bytes(dem.samples.astype(">i2").tobytes())
    return path


GEO_KEYS_WGS84 = (1, 1, 0, 3, 1024, 0, 1, 2, 1025, 0, 1, 1, 2048, 0, 1, 4326)


def write_geotiff(
    path: Path,
    dem: Dem,
    window: tuple[int, int, int, int] | None = None,
    geo_keys: tuple[int, ...] = GEO_KEYS_WGS84,
    tiepoint: bool = True,
    compression: str | None = "zlib",
) -> Path:
    """A window (row0, row1, col0, col1) of the DEM as a pixel-is-area GeoTIFF in EPSG:4326
    (GeoTIFF 1.1): the tiepoint ties raster (0, 0), the outer corner of the first pixel,
    to the model; voids marked by GDAL_NODATA."""
    r0, r1, c0, c1 = window or (0, dem.samples.shape[0], 0, dem.samples.shape[1])
    lat, lon = dem.latlon(r0, c0)
    tags = [
        (33550, "d", 3, (dem.step, dem.step, 0.0), True),
        (34735, "H", len(geo_keys), geo_keys, True),
        (42113, "s", 0, f"{SRTM_VOID}", True),
    ]
    if tiepoint:
        corner = (0.0, 0.0, 0.0, lon - dem.step / 2, lat + dem.step / 2, 0.0)
        tags.append((33922, "d", 6, corner, True))
    tifffile.imwrite(
        path, dem.samples[r0:r1, c0:c1], compression=compression, extratags=tags,
        photometric="minisblack",
    )  # fmt: skip
    return path
