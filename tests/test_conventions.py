"""Pins every convention of ../shared/conventions.md with actual values."""

from __future__ import annotations

import math

import numpy as np
import pytest

from panomap.camera.model import CameraModel
from panomap.camera.radial import RadialFunction
from panomap.geometry import azimuth_elevation, ray_from_angles, wrap_azimuth
from panomap.table.table import PanoMappingTable, fill_entries
from panomap.views import Band, CylinderPanorama, GenericPanorama, PlaneView, build_map


def make_table(m: int = 8, n: int = 4, s: int = 1, phi0: float = 0.0) -> PanoMappingTable:
    """An equidistant camera, r = 100 alpha, centre (50, 60), elevation -90..0 deg."""
    model = CameraModel((50.0, 60.0), RadialFunction("odd1", (100.0,), "down"), s, phi0)
    rng = (-math.pi / 2, 0.0)
    return PanoMappingTable(fill_entries(model, (m, n), rng), rng, model, (0.0, 0.0, 2.0), None, 0.0, 160.0)


def test_azimuth_counter_clockwise_from_plus_x_elevation_negative_below() -> None:
    rays = np.array([[1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0], [1, 0, -1], [1, 0, 1], [0, 0, -1]], float)
    theta, rho = azimuth_elevation(rays)
    np.testing.assert_allclose(theta[:4], [0, math.pi / 2, math.pi, 3 * math.pi / 2])
    np.testing.assert_allclose(rho[4:], [-math.pi / 4, math.pi / 4, -math.pi / 2])
    assert np.all((theta >= 0) & (theta < 2 * math.pi))


def test_azimuth_wraps_into_zero_to_two_pi() -> None:
    assert wrap_azimuth(-1e-18) == 0.0
    assert wrap_azimuth(2 * math.pi) == 0.0
    np.testing.assert_allclose(wrap_azimuth(-math.pi / 2), 3 * math.pi / 2)


def test_zero_ray_has_no_angles() -> None:
    theta, rho = azimuth_elevation(np.zeros(3))
    assert math.isnan(float(theta)) and math.isnan(float(rho))


def test_ray_from_angles_inverts_azimuth_elevation() -> None:
    theta = np.array([0.1, 2.0, 4.0, 6.2])
    rho = np.array([-1.2, -0.3, 0.2, 1.0])
    back = azimuth_elevation(ray_from_angles(theta, rho))
    np.testing.assert_allclose(back[0], theta, atol=1e-12)
    np.testing.assert_allclose(back[1], rho, atol=1e-12)


def test_image_model_u_right_v_down_phi_s_theta_plus_phi0() -> None:
    model = CameraModel((50.0, 60.0), RadialFunction("odd1", (100.0,), "down"))
    # Elevation -45 deg is alpha = 45 deg from the axis: r = 100 * pi/4.
    r = 100 * math.pi / 4
    np.testing.assert_allclose(model.pixels(0.0, -math.pi / 4), [50 + r, 60])
    # Azimuth +90 deg is image angle +90 deg, i.e. down the image (v grows).
    np.testing.assert_allclose(model.pixels(math.pi / 2, -math.pi / 4), [50, 60 + r], atol=1e-12)
    mirrored = CameraModel((50.0, 60.0), model.radial, -1, math.pi / 2)
    # phi = -theta + pi/2: azimuth 0 lands at image angle +90 deg.
    np.testing.assert_allclose(mirrored.pixels(0.0, -math.pi / 4), [50, 60 + r], atol=1e-12)
    np.testing.assert_allclose(model.pixels(1.0, -math.pi / 2), [50, 60], atol=1e-12)


def test_table_entries_follow_eqs_5_to_8() -> None:
    table = make_table(m=8, n=4)
    np.testing.assert_allclose(table.azimuths(), 2 * math.pi * np.arange(8) / 8)
    np.testing.assert_allclose(table.elevations(), -math.pi / 2 + np.arange(4) * (math.pi / 2) / 4)
    # Entry (i=2, j=1): theta = 90 deg, rho = -67.5 deg -> alpha = 22.5 deg.
    r = 100 * math.radians(22.5)
    np.testing.assert_allclose(table.entries[2, 1], [50, 60 + r], atol=1e-4)
    np.testing.assert_allclose(table.entries[:, 0], np.tile([50, 60], (8, 1)), atol=1e-4)


def test_bilinear_sampling_hits_entries_at_nodes_and_wraps_in_azimuth() -> None:
    table = make_table(m=8, n=4)
    thetas, rhos = np.meshgrid(table.azimuths(), table.elevations(), indexing="ij")
    np.testing.assert_allclose(table.sample(thetas, rhos), table.entries, atol=1e-5)
    # Halfway between i = 7 and i = 0 (the seam): the mean of the two entries.
    between = table.sample(2 * math.pi * 7.5 / 8, table.elevations()[2])
    np.testing.assert_allclose(between, (table.entries[7, 2] + table.entries[0, 2]) / 2, atol=1e-5)


def test_nearest_sampling_uses_floor_indices_as_in_the_paper() -> None:
    table = make_table(m=8, n=4)
    step_theta, step_rho = 2 * math.pi / 8, (math.pi / 2) / 4
    # Just below the next node: floor keeps the lower index.
    theta = 3 * step_theta + 0.99 * step_theta
    rho = -math.pi / 2 + 2 * step_rho + 0.99 * step_rho
    np.testing.assert_allclose(table.sample(theta, rho, "nearest"), table.entries[3, 2])


def test_sampling_outside_the_elevation_range_is_nan() -> None:
    table = make_table()
    assert np.all(np.isnan(table.sample(0.0, 0.01)))
    assert np.all(np.isfinite(table.sample(0.0, 0.0)))  # rho_e itself is inside


def test_generic_panorama_columns_decrease_in_azimuth_rows_decrease_in_elevation() -> None:
    table = make_table(m=8, n=4)
    theta, rho = GenericPanorama(size=(4, 2), theta_start_rad=0.0).angles(table)
    # Column k sees theta_start_rad - 2 pi (k + 0.5)/W, wrapped.
    np.testing.assert_allclose(theta[0], np.mod(-2 * math.pi * (np.arange(4) + 0.5) / 4, 2 * math.pi))
    # Row l sees rho_e - (l + 0.5)/H of the range: the top row is the highest.
    np.testing.assert_allclose(rho[:, 0], [-math.pi / 8, -3 * math.pi / 8])


def test_generic_panorama_of_table_size_with_nearest_is_the_table_itself() -> None:
    table = make_table(m=8, n=4)
    map_uv = build_map(table, GenericPanorama(), "nearest")
    # Column k holds entry M-1-k, row l entry N-1-l: the paper's table, upright and not mirrored.
    np.testing.assert_allclose(map_uv, table.entries[::-1, ::-1].transpose(1, 0, 2))


def test_cylinder_pixels_see_points_at_distance_and_band_heights() -> None:
    view = CylinderPanorama(2.0, Band(-1.0, 0.5), (4, 3), theta_start_rad=math.pi / 2)
    points = view.points(make_table())
    np.testing.assert_allclose(np.hypot(points[..., 0], points[..., 1]), 2.0)
    np.testing.assert_allclose(points[:, 0, 2], [0.25, -0.25, -0.75])  # z_top - (l + 0.5)(z_top - z_bottom)/H
    theta, rho = view.angles(make_table())
    np.testing.assert_allclose(theta[0, 0], math.pi / 2 - 2 * math.pi * 0.5 / 4)
    np.testing.assert_allclose(rho[:, 0], np.arctan2([0.25, -0.25, -0.75], 2.0))


def test_plane_edges_at_distance_d_left_at_higher_azimuth() -> None:
    view = PlaneView(distance=2.0, width=2.0, band=Band(-1.0, 0.0), azimuth_rad=math.radians(30), size=(1000, 2))
    phi = math.acos(1 - 4.0 / 8.0)  # eq. 13: 60 deg for W_p = D
    assert view.subtended == pytest.approx(phi)
    points = view.points(make_table())
    theta, _ = azimuth_elevation(points)
    # The first and last pixel centres lie half a pixel inside the edges at theta_c +- phi/2.
    assert theta[0, 0] == pytest.approx(math.radians(30) + phi / 2, abs=2e-3)
    assert theta[0, -1] == pytest.approx(math.radians(30) - phi / 2, abs=2e-3)
    np.testing.assert_allclose(np.linalg.norm(points[0, 0, :2] - points[0, -1, :2]), 2.0 * 999 / 1000, rtol=1e-9)
    # The plane is straight: every point lies on the chord between the edges.
    chord = points[0, -1, :2] - points[0, 0, :2]
    offsets = points[0, :, :2] - points[0, 0, :2]
    np.testing.assert_allclose(chord[0] * offsets[:, 1] - chord[1] * offsets[:, 0], 0, atol=1e-12)
    np.testing.assert_allclose(points[:, 0, 2], [-0.25, -0.75])
