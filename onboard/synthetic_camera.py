"""Synthetic camera for simulated gear: JPEG views of a textured ground plane.

The ground is the NED plane d = 0 painted with a deterministic texture in world
coordinates (checkerboard, coloured grid lines, smooth colour blobs), so two pictures
differ when taken from different places and a rotation of the camera is visible. Tests
and the past-image view get real, decodable images without a real camera.

Conventions: positions are NED metres, orientations are body-to-world quaternions
``(qx, qy, qz, qw)`` with the body frame forward-right-down (x forward, y right, z down).
"""

from __future__ import annotations

import io
import math
from functools import lru_cache

try:
    import numpy as np
    from PIL import Image
except ImportError as exc:  # the package's optional `camera` extra
    raise ImportError(
        "The synthetic camera needs numpy and Pillow: pip install 'skyhive-onboard[camera]'"
    ) from exc

EARTH_RADIUS_M = 6_378_137.0

# The forward camera's defaults: the past-image view must use the same mount tilt and
# field of view to place the drone in these pictures.
VIEW_FOV_DEG = 90.0
VIEW_PITCH_DOWN_DEG = 30.0

SKY_TOP = np.array([70.0, 120.0, 200.0], dtype=np.float32)
SKY_HORIZON = np.array([185.0, 210.0, 235.0], dtype=np.float32)
HAZE = np.array([170.0, 180.0, 175.0], dtype=np.float32)
# Beyond this range the texture fades into haze: it would only alias into noise.
HAZE_START_M = 40.0
HAZE_FULL_M = 160.0

CHECKER_M = 1.0
GRID_M = 5.0
GRID_HALF_WIDTH_M = 0.1
BLOB_CELL_M = 4
NORTH_LINE = np.array([220.0, 40.0, 40.0])  # lines of constant north: red
EAST_LINE = np.array([40.0, 70.0, 220.0])  # lines of constant east: blue
HOME_RADIUS_M = 0.5  # a white disc marks home (0, 0)
HOME_PIXEL = np.uint32(0xFFFFFFFF)

# The rendered ground samples a precomputed tile of the pattern: 0.2 m texels, repeating
# every 204.8 m, larger than any test flight (4 MB of RGBX).
TEXELS_PER_M = 5
TEXTURE_SIZE = 1024
TEXTURE_PERIOD_M = TEXTURE_SIZE / TEXELS_PER_M


def orientation_from_euler(
    roll_deg: float, pitch_deg: float, yaw_deg: float
) -> tuple[float, float, float, float]:
    """Body-to-NED quaternion (qx, qy, qz, qw) from aerospace Z-Y-X Euler angles."""
    cr, sr = math.cos(math.radians(roll_deg) / 2), math.sin(math.radians(roll_deg) / 2)
    cp, sp = math.cos(math.radians(pitch_deg) / 2), math.sin(math.radians(pitch_deg) / 2)
    cy, sy = math.cos(math.radians(yaw_deg) / 2), math.sin(math.radians(yaw_deg) / 2)
    return (
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
        cr * cp * cy + sr * sp * sy,
    )


def _rotation_matrix(orientation: tuple[float, float, float, float]) -> np.ndarray:
    q = np.asarray(orientation, dtype=float)
    norm = float(np.linalg.norm(q)) if q.shape == (4,) else float("nan")
    if not math.isfinite(norm) or norm < 1e-9:
        raise ValueError(f"orientation must be 4 finite numbers, not all zero: {orientation}")
    x, y, z, w = q / norm
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


@lru_cache(maxsize=16)
def _body_rays(width: int, height: int, fov_deg: float, pitch_down_deg: float) -> np.ndarray:
    """Unit ray direction of every pixel in the body frame, shape (H*W, 3), row-major."""
    half = math.tan(math.radians(fov_deg) / 2)  # fov is horizontal
    xs = ((np.arange(width) + 0.5) / width * 2 - 1) * half
    ys = ((np.arange(height) + 0.5) / height * 2 - 1) * half * (height / width)
    px, py = np.meshgrid(xs, ys)
    theta = math.radians(pitch_down_deg)
    forward = np.array([math.cos(theta), 0.0, math.sin(theta)])
    right = np.array([0.0, 1.0, 0.0])
    down = np.array([-math.sin(theta), 0.0, math.cos(theta)])
    rays = forward + px.reshape(-1, 1) * right + py.reshape(-1, 1) * down
    rays /= np.linalg.norm(rays, axis=1, keepdims=True)
    rays = rays.astype(np.float32)
    rays.setflags(write=False)
    return rays


def _blobs(n: np.ndarray, e: np.ndarray) -> np.ndarray:
    """Smooth colour noise in 0..1: bilinear interpolation of random lattice colours.

    `n` and `e` broadcast together (a column of norths against a row of easts gives the
    grid); the result has their shape and a last axis of 3.
    """
    cells = int(TEXTURE_PERIOD_M * 10) // (BLOB_CELL_M * 10)
    lattice = np.random.default_rng(20160601).random((cells, cells, 3))
    gn, ge = n / BLOB_CELL_M, e / BLOB_CELL_M
    i0, j0 = np.floor(gn), np.floor(ge)
    # Smoothstep weights, so the blobs show no lattice creases.
    fn, fe = gn - i0, ge - j0
    fn = (fn * fn * (3 - 2 * fn))[..., None]
    fe = (fe * fe * (3 - 2 * fe))[..., None]
    i, j = i0.astype(np.int64) % cells, j0.astype(np.int64) % cells
    i1, j1 = (i + 1) % cells, (j + 1) % cells
    west = lattice[i, j] + (lattice[i1, j] - lattice[i, j]) * fn
    east = lattice[i, j1] + (lattice[i1, j1] - lattice[i, j1]) * fn
    return west + (east - west) * fe


def ground_colour(n: np.ndarray, e: np.ndarray) -> np.ndarray:
    """RGB (float 0..255) of the ground pattern at NED points (n, e), away from home.

    `n` and `e` broadcast together, and the result has their shape and a last axis of 3:
    a column of norths against a row of easts computes each row's and each column's terms
    once, not once per point. Rendering samples a precomputed tile of it.
    """
    n, e = np.asarray(n, dtype=float), np.asarray(e, dtype=float)
    checker = ((np.floor(n / CHECKER_M) + np.floor(e / CHECKER_M)) % 2)[..., None]
    colour = (60.0 + 130.0 * _blobs(n, e)) * (0.75 + 0.25 * checker)
    points = colour.shape[:-1]
    on_north_line = np.abs(n - GRID_M * np.round(n / GRID_M)) < GRID_HALF_WIDTH_M
    colour[np.broadcast_to(on_north_line, points)] = NORTH_LINE
    on_east_line = np.abs(e - GRID_M * np.round(e / GRID_M)) < GRID_HALF_WIDTH_M
    colour[np.broadcast_to(on_east_line, points)] = EAST_LINE
    return colour


def _pack(rgb: np.ndarray) -> np.ndarray:
    """Float RGB (N, 3) to RGBX pixels packed one per uint32, so gathers move one word."""
    rgbx = np.full((len(rgb), 4), 255, dtype=np.uint8)
    rgbx[:, :3] = np.clip(rgb, 0, 255)
    return rgbx.view(np.uint32).ravel()


def _unpack(pixels: np.ndarray) -> np.ndarray:
    return pixels.view(np.uint8).reshape(-1, 4)[:, :3].astype(np.float32)


@lru_cache(maxsize=1)
def _texture() -> np.ndarray:
    """One period of the ground pattern at texel centres, packed RGBX (SIZE*SIZE,)."""
    centres = (np.arange(TEXTURE_SIZE) + 0.5) / TEXELS_PER_M
    rows = ground_colour(centres[:, None], centres[None, :])  # north by row, east by column
    table = _pack(rows.reshape(-1, 3))
    table.setflags(write=False)
    return table


@lru_cache(maxsize=1)
def _sky() -> np.ndarray:
    """Packed sky colour for 256 steps of the ray's upward component, horizon to zenith."""
    up = np.linspace(0.0, 1.0, 256, dtype=np.float32)[:, None]
    table = _pack(SKY_HORIZON + (SKY_TOP - SKY_HORIZON) * up)
    table.setflags(write=False)
    return table


def _render(
    position_ned: tuple[float, float, float],
    rotation: np.ndarray,
    *,
    width: int,
    height: int,
    fov_deg: float,
    pitch_down_deg: float,
    quality: int,
) -> bytes:
    out = _pixels(
        position_ned,
        rotation,
        width=width,
        height=height,
        fov_deg=fov_deg,
        pitch_down_deg=pitch_down_deg,
    )
    image = Image.frombuffer("RGBX", (width, height), out, "raw", "RGBX", 0, 1)
    buffer = io.BytesIO()
    image.save(buffer, format="JPEG", quality=int(quality))
    return buffer.getvalue()


def _pixels(
    position_ned: tuple[float, float, float],
    rotation: np.ndarray,
    *,
    width: int,
    height: int,
    fov_deg: float,
    pitch_down_deg: float,
) -> np.ndarray:
    """The view as packed RGBX pixels, row by row (one uint32 each)."""
    if width < 2 or height < 2:
        raise ValueError(f"image size must be at least 2x2, got {width}x{height}")
    if not 1.0 <= fov_deg <= 170.0:
        raise ValueError(f"fov_deg must be within 1..170, got {fov_deg}")
    p = np.asarray(position_ned, dtype=float)
    if p.shape != (3,) or not np.all(np.isfinite(p)):
        raise ValueError(f"position must be three finite numbers, got {position_ned}")
    rays = _body_rays(width, height, float(fov_deg), float(pitch_down_deg)) @ rotation.T.astype(
        np.float32
    )
    down = rays[:, 2]
    height_above = -p[2]
    ground = (down > 1e-4) & (height_above > 0)
    hits = np.flatnonzero(ground)
    out = np.empty(len(rays), dtype=np.uint32)

    # Sky: a gradient in the world "up" component of the ray, so roll tilts the horizon.
    sky = np.flatnonzero(~ground)
    out[sky] = _sky()[(np.clip(-down[sky], 0.0, 1.0) * 255).astype(np.intp)]

    rng = np.float32(height_above) / down[hits]  # rays are unit: t is the range
    gn = np.float32(p[0]) + rng * rays[hits, 0]
    ge = np.float32(p[1]) + rng * rays[hits, 1]
    i = np.floor(gn * TEXELS_PER_M).astype(np.intp) & (TEXTURE_SIZE - 1)
    j = np.floor(ge * TEXELS_PER_M).astype(np.intp) & (TEXTURE_SIZE - 1)
    colour = _texture()[i * TEXTURE_SIZE + j]
    colour[gn * gn + ge * ge < HOME_RADIUS_M**2] = HOME_PIXEL
    hazy = np.flatnonzero(rng > HAZE_START_M)
    if len(hazy):
        fog = np.minimum((rng[hazy] - HAZE_START_M) / (HAZE_FULL_M - HAZE_START_M), 1.0)
        near = _unpack(colour[hazy])
        colour[hazy] = _pack(near + (HAZE - near) * fog[:, None])
    out[hits] = colour
    return out


def render_view(
    position_ned: tuple[float, float, float],
    orientation: tuple[float, float, float, float],
    *,
    width: int = 320,
    height: int = 240,
    fov_deg: float = VIEW_FOV_DEG,
    pitch_down_deg: float = VIEW_PITCH_DOWN_DEG,
    quality: int = 80,
) -> bytes:
    """JPEG seen by a body-mounted camera looking forward, tilted down by pitch_down_deg.

    ``fov_deg`` is the horizontal field of view. Rays that miss the ground (above the
    horizon, or from a camera at or below the ground) show the sky.
    """
    return _render(
        position_ned,
        _rotation_matrix(orientation),
        width=width,
        height=height,
        fov_deg=fov_deg,
        pitch_down_deg=pitch_down_deg,
        quality=quality,
    )


def render_view_rgb(
    position_ned: tuple[float, float, float],
    orientation: tuple[float, float, float, float],
    *,
    width: int = 320,
    height: int = 240,
    fov_deg: float = VIEW_FOV_DEG,
    pitch_down_deg: float = VIEW_PITCH_DOWN_DEG,
) -> np.ndarray:
    """The same view as render_view, as an RGB array (height x width x 3, uint8) for a
    video encoder rather than a JPEG."""
    out = _pixels(
        position_ned,
        _rotation_matrix(orientation),
        width=width,
        height=height,
        fov_deg=fov_deg,
        pitch_down_deg=pitch_down_deg,
    )
    return out.view(np.uint8).reshape(height, width, 4)[:, :, :3]


def ned_from_geodetic(
    lat: float, lon: float, alt: float, home: tuple[float, float]
) -> tuple[float, float, float]:
    """Local NED metres of (lat, lon, alt above home) around home, flat-earth approximation."""
    lat0, lon0 = home
    north = math.radians(lat - lat0) * EARTH_RADIUS_M
    east = math.radians(lon - lon0) * EARTH_RADIUS_M * math.cos(math.radians(lat0))
    return (north, east, -alt)


def render_nadir(
    lat: float,
    lon: float,
    alt: float,
    yaw_deg: float,
    *,
    home: tuple[float, float],
    width: int = 320,
    height: int = 240,
    fov_deg: float = 70.0,
    quality: int = 85,
) -> bytes:
    """JPEG from a straight-down picture camera; the top of the image points to yaw_deg.

    ``alt`` is metres above home's ground; below 0.1 m it is clamped so the picture
    still shows the ground.
    """
    north, east, down = ned_from_geodetic(lat, lon, max(alt, 0.1), home)
    return _render(
        (north, east, down),
        _rotation_matrix(orientation_from_euler(0.0, 0.0, yaw_deg)),
        width=width,
        height=height,
        fov_deg=fov_deg,
        pitch_down_deg=90.0,
        quality=quality,
    )
