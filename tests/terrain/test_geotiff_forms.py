"""GeoTIFF forms real elevation models come in (GDAL's and PROJ's test grids showed each):
a stored value with a scale and offset, a placement by ModelTransformationTag, rows from
south to north, and predictors that do not fit the samples."""

from __future__ import annotations

import io
import struct

import numpy as np
import pytest
import tifffile

from terrain.formats import TerrainError, read_dem

RAW = np.arange(1, 17, dtype=np.uint16).reshape(4, 4)
# Pixel-is-point (GTRasterTypeGeoKey 2): the tiepoint names the first sample itself.
POINT_KEYS = (1, 1, 0, 3, 1024, 0, 1, 2, 1025, 0, 1, 2, 2048, 0, 1, 4326)


def geotiff(samples: np.ndarray, *tags: tuple, **kwargs) -> bytes:
    out = io.BytesIO()
    keys = (34735, "H", len(POINT_KEYS), POINT_KEYS, True)
    tifffile.imwrite(out, samples, extratags=[keys, *tags], photometric="minisblack", **kwargs)
    return out.getvalue()


def placed(scale_y: float = 1.0, top: float = 55.0) -> list[tuple]:
    return [
        (33550, "d", 3, (1.0, scale_y, 0.0), True),
        (33922, "d", 6, (0.0, 0.0, 0.0, 4.0, top, 0.0), True),
    ]


def test_gdal_scale_and_offset_turn_stored_values_into_metres_and_nodata_stays_a_void():
    metadata = (
        '<GDALMetadata><Item name="OFFSET" sample="0" role="offset">-5</Item>'
        '<Item name="SCALE" sample="0" role="scale">0.5</Item></GDALMetadata>'
    )
    data = geotiff(RAW, *placed(), (42112, "s", 0, metadata, True), (42113, "s", 0, "16", True))
    grid = read_dem("scaled.tif", data, 1_000_000)
    assert grid.heights[0, 0] == pytest.approx(1 * 0.5 - 5)
    assert grid.heights[3, 2] == pytest.approx(15 * 0.5 - 5)
    assert np.isnan(grid.heights[3, 3])  # the stored 16, before scaling


def test_a_model_transformation_without_rotation_places_the_grid_as_tiepoint_and_scale_do():
    matrix = (1.0, 0.0, 0.0, 4.0, 0.0, -1.0, 0.0, 55.0, 0, 0, 0, 0, 0, 0, 0, 1.0)
    by_matrix = read_dem("m.tif", geotiff(RAW, (34264, "d", 16, matrix, True)), 1_000_000)
    by_tags = read_dem("t.tif", geotiff(RAW, *placed()), 1_000_000)
    assert (by_matrix.north, by_matrix.west, by_matrix.dlat, by_matrix.dlon) == (
        by_tags.north,
        by_tags.west,
        by_tags.dlat,
        by_tags.dlon,
    )
    np.testing.assert_array_equal(by_matrix.heights, by_tags.heights)
    rotated = (1.0, 0.2, 0.0, 4.0, 0.1, -1.0, 0.0, 55.0, 0, 0, 0, 0, 0, 0, 0, 1.0)
    with pytest.raises(TerrainError, match="rotates the grid"):
        read_dem("r.tif", geotiff(RAW, (34264, "d", 16, rotated, True)), 1_000_000)


def test_rows_from_south_to_north_are_turned_north_up():
    north_up = read_dem("n.tif", geotiff(RAW, *placed()), 1_000_000)
    # The same ground stored bottom-up: its first row is the southmost, at 52°.
    bottom_up = read_dem("b.tif", geotiff(RAW[::-1].copy(), *placed(-1.0, 52.0)), 1_000_000)
    assert (bottom_up.north, bottom_up.dlat) == (north_up.north, north_up.dlat) == (55.0, 1.0)
    np.testing.assert_array_equal(bottom_up.heights, north_up.heights)


def _marked(samples: np.ndarray, predictor: int) -> bytes:
    """Written with the horizontal predictor tifffile can encode, then marked with another
    (the Predictor entry's value 2 becomes `predictor`)."""
    data = geotiff(samples, *placed(), compression="zlib", predictor=True)
    entry = struct.pack("<HHIH", 317, 3, 1, 2)
    assert data.count(entry) == 1
    return data.replace(entry, struct.pack("<HHIH", 317, 3, 1, predictor))


def test_predictors_that_do_not_fit_the_samples_are_refused_before_decoding():
    with pytest.raises(TerrainError, match="floating-point predictor on whole numbers"):
        read_dem("marked.tif", _marked(RAW, 3), 1_000_000)
    with pytest.raises(TerrainError, match=r"predictor \(TIFF code 4\) is not supported"):
        read_dem("marked.tif", _marked(RAW, 4), 1_000_000)
