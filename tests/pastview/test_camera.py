import io

import numpy as np
import pytest
from PIL import Image

from onboard.synthetic_camera import orientation_from_euler, render_nadir, render_view

LEVEL_NORTH = orientation_from_euler(0.0, 0.0, 0.0)


def decode(jpeg: bytes) -> np.ndarray:
    image = Image.open(io.BytesIO(jpeg))
    assert image.format == "JPEG"
    return np.asarray(image.convert("RGB"), dtype=float)


def mean_difference(a: bytes, b: bytes) -> float:
    return float(np.abs(decode(a) - decode(b)).mean())


def test_a_view_is_a_decodable_jpeg_of_the_requested_size():
    pixels = decode(render_view((0.0, 0.0, -5.0), LEVEL_NORTH, width=160, height=120))

    assert pixels.shape == (120, 160, 3)


def test_the_same_pose_renders_the_same_picture():
    first = render_view((3.0, 4.0, -5.0), LEVEL_NORTH)
    second = render_view((3.0, 4.0, -5.0), LEVEL_NORTH)

    assert first == second


def test_pictures_taken_at_different_places_differ():
    here = render_view((0.0, 0.0, -5.0), LEVEL_NORTH)
    there = render_view((7.3, -11.1, -5.0), LEVEL_NORTH)

    assert mean_difference(here, there) > 10


def test_a_rotation_of_the_camera_changes_the_picture():
    north = render_view((0.0, 0.0, -5.0), LEVEL_NORTH)
    east = render_view((0.0, 0.0, -5.0), orientation_from_euler(0.0, 0.0, 90.0))

    assert mean_difference(north, east) > 10


def test_the_sky_fills_the_top_of_a_level_forward_view_and_the_ground_the_bottom():
    pixels = decode(render_view((0.0, 0.0, -5.0), LEVEL_NORTH, pitch_down_deg=0.0))
    top, bottom = pixels[:20].mean(axis=(0, 1)), pixels[-20:].mean(axis=(0, 1))

    assert top[2] > top[0] + 30  # blue sky
    assert np.abs(top - bottom).sum() > 30


def test_rolling_right_tilts_the_horizon_so_the_sky_reaches_lower_on_the_right():
    pixels = decode(
        render_view((0.0, 0.0, -5.0), orientation_from_euler(20.0, 0.0, 0.0), pitch_down_deg=0)
    )
    blue = pixels[:, :, 2] - pixels[:, :, 0] > 40
    sky_rows_left = blue[:, :40].sum(axis=0).mean()
    sky_rows_right = blue[:, -40:].sum(axis=0).mean()

    assert sky_rows_left > sky_rows_right + 20


def test_a_nadir_picture_above_home_shows_the_white_home_marker_in_the_centre():
    pixels = decode(render_nadir(40.6303, -8.6575, 3.0, 0.0, home=(40.6303, -8.6575)))
    centre = pixels[115:125, 155:165].mean(axis=(0, 1))

    assert centre.min() > 230


def test_a_nadir_picture_changes_with_the_heading():
    north = render_nadir(40.6304, -8.6574, 10.0, 0.0, home=(40.6303, -8.6575))
    east = render_nadir(40.6304, -8.6574, 10.0, 90.0, home=(40.6303, -8.6575))

    assert mean_difference(north, east) > 10


@pytest.mark.parametrize("bad", [(0.0, 0.0, 0.0, 0.0), (float("nan"), 0.0, 0.0, 1.0), (1.0,)])
def test_an_invalid_orientation_is_refused_with_a_clear_error(bad):
    with pytest.raises(ValueError, match="orientation"):
        render_view((0.0, 0.0, -5.0), bad)


def test_a_non_finite_position_is_refused_with_a_clear_error():
    with pytest.raises(ValueError, match="position"):
        render_view((float("inf"), 0.0, -5.0), LEVEL_NORTH)


def test_the_ground_pattern_on_a_grid_is_the_pattern_at_each_of_its_points():
    """The tile is computed by rows and columns; each texel must still be the colour of
    the pattern at its own point (grid lines, their crossings, the checker, the blobs)."""
    from onboard.synthetic_camera import ground_colour

    norths = np.linspace(-12.0, 12.0, 97)  # crosses grid lines at multiples of 5 m
    easts = np.linspace(-7.3, 19.1, 89)
    grid = ground_colour(norths[:, None], easts[None, :])
    n, e = np.meshgrid(norths, easts, indexing="ij")
    points = ground_colour(n.ravel(), e.ravel())
    assert grid.shape == (97, 89, 3)
    assert np.array_equal(grid.reshape(-1, 3), points)
    assert (points == [220.0, 40.0, 40.0]).all(axis=1).any()  # a north line is in view
    assert (points == [40.0, 70.0, 220.0]).all(axis=1).any()  # and an east line
