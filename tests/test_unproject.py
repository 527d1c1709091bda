"""Pixels back to rays: the inverse of the table, its valid region, and rays meeting a plane."""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest

from panomap.camera.model import CameraModel
from panomap.camera.radial import RadialFunction
from panomap.errors import PanomapError
from panomap.geometry import azimuth_elevation, ray_from_angles, ray_plane_points
from panomap.simulate import SVP_CAMERA_NAMES, standard_cameras
from panomap.table.table import PanoMappingTable, fill_entries

from helpers import learn_table, spread_landmarks

SIZE = (800, 760)
CAMERA_POSITION = (3.1, 2.4, 2.45)
CAMERAS = standard_cameras(SIZE, centre=(412.3, 371.6), s=-1, phi0=0.9)


@functools.cache
def learn(name: str, model: str = "auto") -> PanoMappingTable:
    camera = CAMERAS[name]
    landmarks = spread_landmarks(camera, CAMERA_POSITION, 20, np.random.default_rng(0))
    return learn_table(camera, CAMERA_POSITION, landmarks, SIZE, model=model)[0]


def annulus_pixels(table: PanoMappingTable, radii: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """Pixels (R, A, 2) at image radii and image angles about the table's centre."""
    u0, v0 = table.model.centre
    return np.stack(
        [u0 + radii[:, None] * np.cos(angles)[None, :], v0 + radii[:, None] * np.sin(angles)[None, :]], axis=-1
    )


def valid_radii(table: PanoMappingTable, count: int) -> np.ndarray:
    """Radii across the valid region: the annulus, inside the image, within the table's elevations."""
    u0, v0 = table.model.centre
    width, height = SIZE
    # The radii the table reaches at its two ends (read at an azimuth node, where no chord shortens them).
    ends = table.sample(np.zeros(2), np.array(table.elevation_range)) - np.array([u0, v0])
    reach = np.sort(np.linalg.norm(ends, axis=-1))
    inscribed = min(u0 + 0.5, v0 + 0.5, width - 0.5 - u0, height - 0.5 - v0, table.outer_radius, reach[1])
    return np.linspace(max(table.cutoff_radius, reach[0]) + 1e-3, inscribed - 1e-3, count)


@pytest.mark.parametrize("model", ["auto", "paper"])
@pytest.mark.parametrize("name", SVP_CAMERA_NAMES)
def test_sampling_the_unprojected_rays_gives_the_pixels_back(name: str, model: str) -> None:
    table = learn(name, model)
    # Image angles all round, including the ones that land on the azimuth seam (theta = 0).
    seam = table.model.image_angle(np.array([0.0, 1e-9, 2 * math.pi - 1e-9]))
    angles = np.concatenate([np.linspace(0, 2 * math.pi, 97)[:-1], seam])
    pixels = annulus_pixels(table, valid_radii(table, 60), angles)
    theta, rho = table.unproject(pixels)
    assert np.all(np.isfinite(theta)) and np.all(np.isfinite(rho))
    rho_s, rho_e = table.elevation_range
    assert np.all((rho >= rho_s) & (rho <= rho_e))
    assert np.all((theta >= 0) & (theta < 2 * math.pi))
    back = table.sample(theta, rho)
    # unproject inverts the table's radial profile exactly; what is left is its chords in
    # azimuth (r (pi/M)^2/2 < 4e-4 px for these 2248-entry circles) and float32.
    assert np.max(np.linalg.norm(back - pixels, axis=-1)) < 1e-3


@pytest.mark.parametrize("name", SVP_CAMERA_NAMES)
def test_unprojected_rays_are_the_cameras_rays(name: str) -> None:
    table = learn(name)
    pixels = annulus_pixels(table, valid_radii(table, 25), np.linspace(0, 2 * math.pi, 41)[:-1])
    theta, rho = table.unproject(pixels)
    _origins, directions = CAMERAS[name].trace(pixels)
    true_theta, true_rho = azimuth_elevation(directions)
    # Exact landmarks and a model family holding the camera: only the fit's ~1e-3 px and the
    # table's interpolation (up to 0.02 px in its last cell) remain, 1e-4 rad at these radii.
    gap = np.angle(np.exp(1j * (theta - true_theta)))
    assert np.nanmax(np.abs(gap)) < 1e-4
    assert np.nanmax(np.abs(rho - true_rho)) < 1e-4


def test_outside_the_valid_region_is_nan() -> None:
    table = learn("parabolic")
    u0, v0 = table.model.centre
    outside = np.array(
        [
            [u0, v0],  # the centre: inside the cut-off disc
            [u0 + table.cutoff_radius - 0.5, v0],
            [u0 + table.outer_radius + 0.5, v0],
            [-1.0, v0],  # outside the image
            [np.nan, v0],
            [np.inf, v0],
        ]
    )
    theta, rho = table.unproject(outside)
    assert np.all(np.isnan(theta)) and np.all(np.isnan(rho))
    # The edges of the valid region themselves are inside: the cut-off circle, and the radius
    # the table reaches at rho_e (here just inside the outer radius, where the last cell's
    # straight line ends).
    reach = float(np.linalg.norm(table.sample(0.0, table.elevation_range[1]) - np.array([u0, v0])))
    assert table.outer_radius - 0.05 < reach < table.outer_radius
    edges = np.array([[u0 + table.cutoff_radius, v0], [u0, v0 + reach], [u0, v0 + reach + 0.001]])
    theta, rho = table.unproject(edges)
    assert np.all(np.isfinite(rho[:2])) and np.isnan(rho[2])
    assert rho[0] == pytest.approx(table.elevation_range[0], abs=1e-9)
    assert rho[1] == pytest.approx(table.elevation_range[1], abs=1e-6)


def table_of(radial: RadialFunction, elevations: tuple[float, float], s: int = 1) -> PanoMappingTable:
    model = CameraModel((200.0, 180.0), radial, s, 0.3)
    return PanoMappingTable(
        fill_entries(model, (720, 200), elevations), elevations, model, (0.0, 0.0, 1.0), (400, 360), 0.0, 170.0
    )


def test_camera_looking_up_and_the_centre_pixel() -> None:
    # Equidistant, on the floor looking up: r = 120 alpha with alpha = 90 deg - rho.
    table = table_of(RadialFunction("odd1", (120.0,), "up"), (-0.3, math.pi / 2), s=-1)
    theta, rho = table.unproject(np.array([[200.0, 180.0], [200.0 + 60.0, 180.0]]))
    # The centre sees the zenith; its azimuth is atan2(0, 0) = 0, as for a vertical ray.
    assert rho[0] == pytest.approx(math.pi / 2, abs=1e-12) and theta[0] == 0.0
    # 60 px out is alpha = 0.5 rad (f_r is linear: the profile is exact); image angle 0 is
    # theta = s (phi - phi0) = -(0 - 0.3).
    assert rho[1] == pytest.approx(math.pi / 2 - 0.5, abs=1e-12)
    assert theta[1] == pytest.approx(0.3, abs=1e-12)
    pixels = np.array([[250.0, 200.0], [120.5, 100.25], [330.0, 180.0]])
    # Measured 1.16e-3 px: the bilinear table's chord between this small table's azimuth entries.
    np.testing.assert_allclose(table.sample(*table.unproject(pixels)), pixels, atol=3e-3)


def test_a_radial_function_that_is_not_monotonic_is_refused() -> None:
    # r = 100 rho + 80 rho^2 turns at rho = -0.625: not invertible on -1..0.
    table = table_of(RadialFunction("paper", (100.0, 100.0, 80.0, 0.0, 0.0), "down"), (-1.0, 0.0))
    with pytest.raises(PanomapError, match="not strictly monotonic on its elevation range"):
        table.unproject(np.array([[210.0, 180.0]]))


def test_rays_meet_a_horizontal_plane() -> None:
    origin = (1.0, 2.0, 3.0)
    theta = np.array([0.0, math.pi / 2, 0.0, 0.0, 1.0, np.nan])
    rho = np.array([-math.pi / 4, -math.atan2(1.0, 2.0), 0.0, 0.3, -math.pi / 2, -0.5])
    points = ray_plane_points(origin, theta, rho, 2.0)
    np.testing.assert_allclose(points[0], [2.0, 2.0, 2.0], atol=1e-12)  # 45 deg down, 1 m below: 1 m out
    np.testing.assert_allclose(points[1], [1.0, 4.0, 2.0], atol=1e-12)
    assert np.all(np.isnan(points[2:4]))  # level, or rising: never reaches a plane below
    np.testing.assert_allclose(points[4], [1.0, 2.0, 2.0], atol=1e-12)  # straight down
    assert np.all(np.isnan(points[5]))
    # Points on the plane lie on their rays.
    d = points[:2] - np.asarray(origin)
    np.testing.assert_allclose(
        d / np.linalg.norm(d, axis=-1, keepdims=True), ray_from_angles(theta[:2], rho[:2]), atol=1e-12
    )


def test_unproject_then_meet_the_floor_round_trips_through_project() -> None:
    table = learn("hyperbolic")
    pixels = annulus_pixels(table, valid_radii(table, 12)[:8], np.linspace(0.1, 6.2, 13))
    theta, rho = table.unproject(pixels)
    world = ray_plane_points(table.camera_position, theta, rho, 0.0)
    assert np.all(np.isfinite(world))  # these pixels all look below the horizon
    # Measured 2.8e-4 px (float32 entries); the README promises 1e-3 px.
    assert np.max(np.linalg.norm(table.project(world) - pixels, axis=-1)) < 1e-3
