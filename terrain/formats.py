"""Reading elevation models as their publishers ship them: SRTM `.hgt` tiles and GeoTIFF DEMs.

Both become a `Grid`: elevations in metres (float32, NaN where the model has a void),
row 0 at the north, with the latitude and longitude of the first sample's centre and the
spacing between samples. Nothing here knows the database or the disk layout.

SRTM `.hgt` (SRTM Topography, NASA/USGS; SRTMGL1 and SRTMGL3 user guide): a square of
3601 x 3601 (1 arc-second) or 1201 x 1201 (3 arc-seconds) signed 16-bit big-endian
samples, rows from north to south, no header; the name gives the latitude and longitude
of the centre of the lower-left sample (N38W010: 38° N, 10° W), and the tile's edge rows
and columns are the same samples as its neighbours'. A void is -32768.

GeoTIFF (OGC GeoTIFF 1.1): one band of elevations in EPSG:4326 placed by
ModelTiepointTag (33922) and ModelPixelScaleTag (33550); the GeoKeyDirectoryTag (34735)
says the model is geographic WGS 84 (GTModelTypeGeoKey 1024 = 2, GeodeticCRSGeoKey 2048 =
4326) and whether a pixel is an area or a point (GTRasterTypeGeoKey 1025); a
ModelTransformationTag (34264) without rotation places it as well. The value of GDAL's
GDAL_NODATA tag (42113, ASCII) marks voids, and the band's scale and offset in GDAL's
GDAL_METADATA tag (42112, XML) turn stored values into metres (value x scale + offset).
"""

from __future__ import annotations

import io
import math
import re
from dataclasses import dataclass

import numpy as np

from terrain import tiffcodecs

SRTM_VOID = -32768
# Elevations an SRTM tile can hold (the Dead Sea shore is -430 m, Everest 8849 m): a
# sample beyond them means a file that is not big-endian SRTM data.
SRTM_RANGE = (-1000, 9000)
# Samples per side of the two SRTM resolutions, by arc-seconds between samples.
SRTM_SIDES = {3601: 1, 1201: 3}
HGT_NAME = re.compile(r"^([NS])(\d{2})([EW])(\d{3})(?:\.[A-Za-z0-9]+)*\.hgt$", re.I)

TAG_MODEL_PIXEL_SCALE = 33550
TAG_MODEL_TIEPOINT = 33922
TAG_MODEL_TRANSFORMATION = 34264
TAG_GEO_KEY_DIRECTORY = 34735
TAG_GDAL_NODATA = 42113
TAG_GDAL_METADATA = 42112
# A band's scale or offset in GDAL_METADATA: <Item name="SCALE" sample="0" role="scale">.
GDAL_ITEM = re.compile(
    r"<Item\b(?P<attrs>[^>]*)>\s*(?P<value>[^<]*?)\s*</Item>", re.IGNORECASE | re.DOTALL
)
KEY_MODEL_TYPE = 1024
KEY_RASTER_TYPE = 1025
KEY_GEODETIC_CRS = 2048
KEY_PROJECTED_CRS = 3072
MODEL_TYPE_GEOGRAPHIC = 2
RASTER_PIXEL_IS_POINT = 2
EPSG_WGS84 = 4326
# Compressions read without native codecs: tifffile decodes none, Deflate, LZMA and
# PackBits with the standard library and numpy; LZW is ours (terrain.tiffcodecs).
READABLE_COMPRESSIONS = {
    1: "none",
    5: "LZW",
    8: "Deflate",
    32773: "PackBits",
    32946: "Deflate",
    34925: "LZMA",
}
# Segments decoded by terrain.tiffcodecs rather than tifffile: LZW, or any compression
# with the floating-point predictor (TIFF Predictor 3).
OWN_COMPRESSIONS = {5}
OWN_PREDICTORS = {tiffcodecs.PREDICTOR_FLOATING_POINT}
# A grid must place its samples on the globe within this much of its edges (degrees):
# a pixel-is-area model's outer edges lie half a pixel beyond its outer samples.
EDGE_SLACK = 1e-6


class TerrainError(ValueError):
    """An elevation model that cannot be used, with the reason for the operator."""


@dataclass
class Grid:
    """Elevations in metres, row 0 at the north, NaN for voids.

    `north` and `west` are the latitude and longitude of the centre of sample (0, 0);
    `dlat` and `dlon` the spacing between samples in degrees (both positive).
    """

    name: str
    kind: str
    heights: np.ndarray
    north: float
    west: float
    dlat: float
    dlon: float

    @property
    def rows(self) -> int:
        return int(self.heights.shape[0])

    @property
    def cols(self) -> int:
        return int(self.heights.shape[1])

    @property
    def south(self) -> float:
        return self.north - (self.rows - 1) * self.dlat

    @property
    def east(self) -> float:
        return self.west + (self.cols - 1) * self.dlon

    @property
    def void_count(self) -> int:
        return int(np.count_nonzero(np.isnan(self.heights)))


def read_dem(name: str, data: bytes, max_samples: int) -> Grid:
    """A `.hgt` or GeoTIFF file's grid, told apart by its name (then its magic number)."""
    if HGT_NAME.match(name.rsplit("/", 1)[-1]):
        return read_hgt(name, data)
    if data[:4] in (b"II*\x00", b"MM\x00*", b"II+\x00", b"MM\x00+"):
        return read_geotiff(name, data, max_samples)
    raise TerrainError(
        f"{name} is neither an SRTM .hgt file (named like N38W010.hgt) nor a GeoTIFF"
    )


# -- SRTM .hgt ----------------------------------------------------------------------------


def hgt_origin(name: str) -> tuple[int, int]:
    """(latitude, longitude) of the lower-left sample from a name like N38W010.hgt."""
    match = HGT_NAME.match(name.rsplit("/", 1)[-1])
    if match is None:
        raise TerrainError(f"{name}: an SRTM file is named like N38W010.hgt")
    lat = int(match.group(2)) * (1 if match.group(1).upper() == "N" else -1)
    lon = int(match.group(4)) * (1 if match.group(3).upper() == "E" else -1)
    if not (-90 <= lat <= 89 and -180 <= lon <= 179):
        raise TerrainError(f"{name}: {lat}, {lon} is not the corner of a 1° tile")
    return lat, lon


def read_hgt(name: str, data: bytes) -> Grid:
    """An SRTM tile: its size says its resolution, its name where it lies."""
    lat, lon = hgt_origin(name)
    side = math.isqrt(len(data) // 2)
    if len(data) != 2 * side * side or side not in SRTM_SIDES:
        sizes = " or ".join(f"{2 * n * n} bytes ({n} x {n})" for n in SRTM_SIDES)
        raise TerrainError(
            f"{name} holds {len(data)} bytes; an SRTM .hgt file holds {sizes} 16-bit samples "
            "(truncated or not an SRTM tile)"
        )
    samples = np.frombuffer(data, dtype=">i2").reshape(side, side)
    _check_srtm_range(name, samples)
    heights = samples.astype(np.float32)
    heights[samples == SRTM_VOID] = np.nan
    step = 1.0 / (side - 1)
    return Grid(name, "hgt", heights, lat + 1.0, float(lon), step, step)


def _check_srtm_range(name: str, samples: np.ndarray) -> None:
    low, high = SRTM_RANGE
    wrong = (samples != SRTM_VOID) & ((samples < low) | (samples > high))
    if wrong.any():
        row, col = (int(v) for v in np.argwhere(wrong)[0])
        raise TerrainError(
            f"{name}: sample ({row}, {col}) is {int(samples[row, col])} m, outside {low}..{high} "
            "m: not big-endian SRTM elevations (a little-endian file?)"
        )


# -- GeoTIFF ------------------------------------------------------------------------------


def _geo_keys(directory: tuple | list) -> dict[int, int]:
    """GeoKeyDirectoryTag → {key: value} for the keys stored in the directory itself."""
    values = [int(v) for v in directory]
    if len(values) < 4 or values[0] != 1:
        raise TerrainError("its GeoKeyDirectoryTag is malformed (version 1 expected)")
    count = values[3]
    if len(values) < 4 + 4 * count:
        raise TerrainError("its GeoKeyDirectoryTag holds fewer keys than it declares")
    keys = {}
    for i in range(count):
        key, location, _, value = values[4 + 4 * i : 8 + 4 * i]
        if location == 0:  # the value is in the entry (a SHORT)
            keys[key] = value
    return keys


def _check_crs(keys: dict[int, int]) -> None:
    if KEY_PROJECTED_CRS in keys or keys.get(KEY_MODEL_TYPE) != MODEL_TYPE_GEOGRAPHIC:
        projected = keys.get(KEY_PROJECTED_CRS)
        crs = f"EPSG:{projected}" if projected else f"model type {keys.get(KEY_MODEL_TYPE)}"
        raise TerrainError(
            f"it is in {crs}, not EPSG:4326 (WGS 84 latitude and longitude); reproject it, "
            "e.g. gdalwarp -t_srs EPSG:4326"
        )
    if keys.get(KEY_GEODETIC_CRS) != EPSG_WGS84:
        raise TerrainError(
            f"its geographic CRS is EPSG:{keys.get(KEY_GEODETIC_CRS)}, not EPSG:4326 (WGS 84)"
        )


def _numbers(tag: object, count: int, what: str) -> list[float]:
    value = getattr(tag, "value", None)
    if not isinstance(value, tuple | list) or len(value) < count:
        raise TerrainError(f"its {what} must hold at least {count} numbers")
    numbers = [float(v) for v in value]
    if not all(math.isfinite(v) for v in numbers):
        raise TerrainError(f"its {what} holds a value that is not a finite number")
    return numbers


def _nodata(tags: object) -> float | None:
    tag = tags.get(TAG_GDAL_NODATA)  # type: ignore[attr-defined]
    if tag is None:
        return None
    text = tag.value.decode("ascii", "replace") if isinstance(tag.value, bytes) else tag.value
    try:
        return float(str(text).strip().strip("\x00"))
    except ValueError:
        raise TerrainError(f"its GDAL_NODATA tag {text!r} is not a number") from None


def _scale_offset(tags: object) -> tuple[float, float]:
    """The first band's (scale, offset) from GDAL_METADATA; (1, 0) when it gives none."""
    tag = tags.get(TAG_GDAL_METADATA)  # type: ignore[attr-defined]
    text = getattr(tag, "value", "") or ""
    text = text.decode("utf-8", "replace") if isinstance(text, bytes) else str(text)
    found = {"scale": 1.0, "offset": 0.0}
    for item in GDAL_ITEM.finditer(text):
        attrs = dict(re.findall(r'(\w+)\s*=\s*"([^"]*)"', item.group("attrs")))
        role = attrs.get("role", "").lower()
        if role in found and attrs.get("sample", "0") == "0":
            try:
                found[role] = float(item.group("value"))
            except ValueError:
                raise TerrainError(f"its GDAL_METADATA {role} is not a number") from None
    if not all(math.isfinite(v) for v in found.values()) or found["scale"] == 0:
        raise TerrainError(f"its GDAL_METADATA scale and offset {found} cannot give heights")
    return found["scale"], found["offset"]


def _tiepoint_and_scale(tags: object) -> tuple[list[float], list[float]]:
    """(tiepoint i, j, k, x, y, z; pixel scale x, y) from their tags, or from a
    ModelTransformationTag without rotation (a 4 x 4 matrix: x scale at [0], y scale at
    [5], the origin at [3] and [7])."""
    matrix_tag = tags.get(TAG_MODEL_TRANSFORMATION)  # type: ignore[attr-defined]
    if matrix_tag is not None:
        m = _numbers(matrix_tag, 16, "ModelTransformationTag")
        if m[1] != 0 or m[4] != 0:
            raise TerrainError(
                "its ModelTransformationTag rotates the grid, which is not supported"
            )
        return [0.0, 0.0, 0.0, m[3], m[7], 0.0], [m[0], -m[5]]
    scale_tag = tags.get(TAG_MODEL_PIXEL_SCALE)  # type: ignore[attr-defined]
    tie_tag = tags.get(TAG_MODEL_TIEPOINT)  # type: ignore[attr-defined]
    if scale_tag is None or tie_tag is None:
        raise TerrainError("it has no ModelTiepointTag and ModelPixelScaleTag to place it")
    return _numbers(tie_tag, 6, "ModelTiepointTag")[:6], _numbers(
        scale_tag, 3, "ModelPixelScaleTag"
    )[:2]


def _placement(
    tags: object, keys: dict[int, int], rows: int, cols: int
) -> tuple[float, float, float, float, bool]:
    """(north, west, dlat, dlon) of the sample centres from the tiepoint and pixel scale,
    and whether the rows run from south to north (a negative y scale) and must be turned."""
    (i, j, _, x, y, _), (dlon, dlat) = _tiepoint_and_scale(tags)
    if dlon <= 0 or dlat == 0:
        raise TerrainError(f"its pixel scale ({dlon}, {dlat}) must be positive")
    # Pixel-is-area: raster coordinates name pixel corners, so a sample's centre is half a
    # pixel in (GeoTIFF 1.1, raster space); pixel-is-point: they name the samples.
    offset = 0.0 if keys.get(KEY_RASTER_TYPE) == RASTER_PIXEL_IS_POINT else 0.5
    west = x + (offset - i) * dlon
    first_row = y - (offset - j) * dlat
    bottom_up, dlat = dlat < 0, abs(dlat)
    north = first_row + (rows - 1) * dlat if bottom_up else first_row
    south, east = north - (rows - 1) * dlat, west + (cols - 1) * dlon
    slack = offset * max(dlat, dlon) + EDGE_SLACK
    if not (-90 - slack <= south and north <= 90 + slack):
        raise TerrainError(f"its rows span latitudes {south:.6f}..{north:.6f}, off the globe")
    if not (-180 - slack <= west and east <= 180 + slack):
        raise TerrainError(f"its columns span longitudes {west:.6f}..{east:.6f}, off the globe")
    return north, west, dlat, dlon, bottom_up


def _check_page(page: object, max_samples: int) -> tuple[int, int]:
    """The page is one band of numbers of a size we accept, compressed in a way we read."""
    shape = tuple(page.shape)  # type: ignore[attr-defined]
    if len(shape) != 2 or page.samplesperpixel != 1:  # type: ignore[attr-defined]
        raise TerrainError(f"it holds {shape} samples; an elevation model has one band")
    rows, cols = shape
    if rows < 2 or cols < 2:
        raise TerrainError(f"it is {cols} x {rows} samples; at least 2 x 2 are needed")
    if rows * cols > max_samples:
        raise TerrainError(
            f"it is {cols} x {rows} samples, more than {max_samples}, the limit "
            "(TERRAIN_MAX_SAMPLES); split it into tiles"
        )
    dtype = np.dtype(page.dtype)  # type: ignore[attr-defined]
    if dtype.kind not in "iuf":
        raise TerrainError(f"its samples are {dtype}, not numbers")
    compression = int(page.compression)  # type: ignore[attr-defined]
    if compression not in READABLE_COMPRESSIONS:
        raise TerrainError(
            f"its compression (TIFF code {compression}) is not supported; save it "
            "uncompressed or with Deflate (gdal_translate -co COMPRESS=DEFLATE)"
        )
    predictor = int(page.predictor)  # type: ignore[attr-defined]
    if predictor not in tiffcodecs.PREDICTORS:
        raise TerrainError(f"its predictor (TIFF code {predictor}) is not supported")
    if predictor == tiffcodecs.PREDICTOR_HORIZONTAL and dtype.kind == "f":
        raise TerrainError("it has the horizontal predictor on real numbers, which TIFF forbids")
    return rows, cols


def _samples(page: object, data: bytes) -> np.ndarray:
    """The page's samples, decoded by tifffile or, where it would need native codecs, by
    terrain.tiffcodecs."""
    compression = int(page.compression)  # type: ignore[attr-defined]
    if compression in OWN_COMPRESSIONS or int(page.predictor) in OWN_PREDICTORS:  # type: ignore[attr-defined]
        try:
            return tiffcodecs.decode_page(page, data)
        except tiffcodecs.CodecError as exc:
            raise TerrainError(str(exc)) from None
    return page.asarray()  # type: ignore[attr-defined]


def read_geotiff(name: str, data: bytes, max_samples: int) -> Grid:
    """The first image of a GeoTIFF: one band, EPSG:4326, placed by tiepoint and scale."""
    import tifffile

    try:
        with tifffile.TiffFile(io.BytesIO(data)) as tif:
            page = tif.pages.first
            rows, cols = _check_page(page, max_samples)
            directory = page.tags.get(TAG_GEO_KEY_DIRECTORY)
            if directory is None:
                raise TerrainError("it has no GeoKeyDirectoryTag: a TIFF but not a GeoTIFF")
            keys = _geo_keys(directory.value)
            _check_crs(keys)
            north, west, dlat, dlon, bottom_up = _placement(page.tags, keys, rows, cols)
            nodata = _nodata(page.tags)
            scale, offset = _scale_offset(page.tags)
            samples = _samples(page, data)
            samples = samples[::-1] if bottom_up else samples
    except TerrainError as exc:
        raise TerrainError(f"{name}: {exc}") from None
    except Exception as exc:  # tifffile names what is wrong in its own exceptions
        raise TerrainError(f"{name} is not a readable TIFF ({exc})") from None
    heights = samples.astype(np.float64) * scale + offset if (scale, offset) != (1, 0) else samples
    heights = heights.astype(np.float32)
    if nodata is not None:
        heights[samples == nodata] = np.nan  # GDAL's nodata is a stored value, before scaling
    return Grid(name, "geotiff", heights, north, west, dlat, dlon)
