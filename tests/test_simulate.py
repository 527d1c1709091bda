"""Tests of the simulated cameras and the textured room (panomap.simulate)."""

from __future__ import annotations

import json
import math
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from panomap.errors import PanomapError
from panomap.simulate import (
    SVP_CAMERA_NAMES,
    RadialCamera,
    Room,
    SimulatedCamera,
    SphericalMirrorCamera,
    field_stop,
    load_room,
    render,
    render_rays,
    standard_cameras,
)

DEG = math.pi / 180.0


def _annulus_grid(camera: SimulatedCamera, step: float = 7.3, margin: float = 0.5) -> np.ndarray:
    """(N, 2) pixels on a grid, strictly inside the camera's visible annulus and image."""
    width, height = camera.image_size
    u, v = np.meshgrid(np.arange(0.0, width - 1, step), np.arange(0.0, height - 1, step))
    uv = np.stack([u.ravel(), v.ravel()], axis=-1)
    r = np.hypot(uv[:, 0] - camera.centre[0], uv[:, 1] - camera.centre[1])
    keep = (r > camera.cutoff_radius + margin) & (r < camera.outer_radius - margin)
    return uv[keep]


def _wrap(angle: np.ndarray) -> np.ndarray:
    """Angles wrapped to (-pi, pi]."""
    return np.angle(np.exp(1j * np.asarray(angle)))


# ----------------------------------------------------------------------------------------
# Radial (single-viewpoint) cameras
# ----------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", SVP_CAMERA_NAMES)
def test_radial_round_trip(name: str) -> None:
    cam = standard_cameras(size=(400, 300), seed=3)[name]
    uv = _annulus_grid(cam)
    assert len(uv) > 1000
    origins, directions = cam.trace(uv)
    assert np.all(np.isfinite(directions))
    np.testing.assert_array_equal(origins, 0.0)  # a single viewpoint at O_m
    # Unit directions: only rounding error of a few sin/cos evaluations.
    np.testing.assert_allclose(np.linalg.norm(directions, axis=-1), 1.0, atol=1e-14)
    for distance in (0.3, 4.0):
        back = cam.project(distance * directions)
        # Closed-form laws and inverses: the round trip loses only rounding error, far
        # below 1e-6 px at radii of a few hundred pixels.
        np.testing.assert_allclose(back, uv, atol=1e-6, rtol=0)


@pytest.mark.parametrize(
    ("law", "xi", "alpha_max"),
    [
        ("equidistant", 0.0, 3.0),
        ("equisolid", 0.0, 3.0),
        ("unified", 1.0, 2.5),
        ("unified", 0.8, 2.2),
        ("unified", 0.0, 1.4),
        ("unified", 1.5, 2.2),
        ("stereographic", 0.0, 3.0),
        ("orthographic", 0.0, 1.55),
        ("polynomial", 0.0, 1.75),
    ],
)
def test_alpha_of_radius_inverts_radius(law: str, xi: float, alpha_max: float) -> None:
    cam = RadialCamera(
        name="c",
        law=law,
        scale=250.0,
        xi=xi,
        distortion=(-0.05, 0.008) if law == "polynomial" else (),
        image_size=(100, 100),
        centre=(49.5, 49.5),
        alpha_max=alpha_max,
    )
    alpha = np.linspace(0.0, alpha_max, 1001)
    r = cam.radius(alpha)
    assert np.all(np.diff(r) > 0)
    # Closed-form inverse: the error is a few ulps of the angle (amplified by the law's
    # slope near alpha_max for the steep unified laws).
    np.testing.assert_allclose(cam.alpha_of_radius(r), alpha, atol=1e-12, rtol=0)
    assert np.isnan(cam.alpha_of_radius(-1.0))


def test_closed_form_values_pinned() -> None:
    """Pixels of known rays, computed by hand from the laws and the image model."""
    u0, v0, scale = 200.5, 150.25, 100.0
    common: dict[str, Any] = {"image_size": (401, 301), "centre": (u0, v0), "alpha_max": 100 * DEG}
    eqd = RadialCamera(name="a", law="equidistant", scale=scale, **common)
    eqs = RadialCamera(name="b", law="equisolid", scale=scale, **common)
    par = RadialCamera(name="c", law="unified", xi=1.0, scale=scale, **common)
    hyp = RadialCamera(name="d", law="unified", xi=0.8, scale=scale, **common)
    # Elevation -45 deg: alpha = rho + pi/2 = pi/4 for a down-looking camera.
    r_eqd = scale * math.pi / 4
    r_eqs = 2 * scale * math.sin(math.pi / 8)
    r_par = scale * math.tan(math.pi / 8)  # sin a/(1 + cos a) = tan(a/2)
    r_hyp = scale * math.sin(math.pi / 4) / (0.8 + math.cos(math.pi / 4))
    azimuth_0 = np.array([2.0, 0.0, -2.0])  # azimuth 0, elevation -45 deg
    azimuth_90 = np.array([0.0, 3.0, -3.0])  # azimuth 90 deg, elevation -45 deg
    for cam, r in ((eqd, r_eqd), (eqs, r_eqs), (par, r_par), (hyp, r_hyp)):
        # Tolerances: rounding error of a few trig evaluations at ~100 px.
        np.testing.assert_allclose(cam.project(azimuth_0), [u0 + r, v0], atol=1e-9)
        # phi = theta = +90 deg: +v, i.e. DOWN in the image (v is the row).
        np.testing.assert_allclose(cam.project(azimuth_90), [u0, v0 + r], atol=1e-9)
        np.testing.assert_allclose(cam.radius_of_rho(-45 * DEG), r, atol=1e-9)
        np.testing.assert_allclose(cam.rho_of_radius(r), -45 * DEG, atol=1e-12)
    # The other designed fisheye projections and a lens's polynomial, at alpha = pi/4.
    for law, r, extra in (
        ("stereographic", 2 * scale * math.tan(math.pi / 8), {}),
        ("orthographic", scale * math.sin(math.pi / 4), {}),
        (
            "polynomial",
            scale * (math.pi / 4 + 0.1 * (math.pi / 4) ** 3 - 0.02 * (math.pi / 4) ** 5),
            {"distortion": (0.1, -0.02)},
        ),
    ):
        cam = RadialCamera(name=law, law=law, scale=scale, **{**common, "alpha_max": 85 * DEG}, **extra)
        np.testing.assert_allclose(cam.project(azimuth_0), [u0 + r, v0], atol=1e-9)
        np.testing.assert_allclose(cam.rho_of_radius(r), -45 * DEG, atol=1e-12)
    # Straight down lands on the image centre (alpha = 0).
    np.testing.assert_allclose(eqd.project([0.0, 0.0, -1.0]), [u0, v0], atol=1e-12)
    # Horizontal ray (alpha = 90 deg) of a parabolic mirror: r = scale.
    np.testing.assert_allclose(par.project([0.0, -1.0, 0.0]), [u0, v0 - scale], atol=1e-9)
    assert eqd.elevation_range == pytest.approx((-90 * DEG, 10 * DEG), abs=1e-15)


def test_up_looking_camera() -> None:
    cam = RadialCamera(
        name="up",
        law="equidistant",
        scale=100.0,
        image_size=(401, 401),
        centre=(200.0, 200.0),
        axis="up",
        alpha_min=5 * DEG,
        alpha_max=100 * DEG,
    )
    # alpha = pi/2 - rho: elevation +30 deg at azimuth 0 is alpha = 60 deg.
    d = np.array([math.cos(30 * DEG), 0.0, math.sin(30 * DEG)])
    np.testing.assert_allclose(cam.project(d), [200.0 + 100.0 * 60 * DEG, 200.0], atol=1e-9)
    assert cam.elevation_range == pytest.approx((-10 * DEG, 85 * DEG), abs=1e-15)
    assert np.isnan(cam.project([0.0, 0.0, 1.0])).all()  # straight up is inside the cut-off
    uv = _annulus_grid(cam)
    _, directions = cam.trace(uv)
    np.testing.assert_allclose(cam.project(directions), uv, atol=1e-6, rtol=0)


@pytest.mark.parametrize(("s", "phi0"), [(1, 0.0), (-1, 0.0), (1, 0.7), (-1, -2.1)])
def test_handedness_and_offset(s: int, phi0: float) -> None:
    cams = standard_cameras(size=(300, 300), s=s, phi0=phi0)
    theta = np.linspace(0.0, 2 * np.pi, 13, endpoint=False) + 0.1
    rho = -30 * DEG
    d = np.stack(
        [np.cos(rho) * np.cos(theta), np.cos(rho) * np.sin(theta), np.full_like(theta, np.sin(rho))],
        axis=-1,
    )
    for cam in cams.values():
        assert cam.s == s and cam.phi0 == phi0
        uv = cam.project(3.0 * d)
        u0, v0 = cam.centre
        phi = np.arctan2(uv[:, 1] - v0, uv[:, 0] - u0)
        # Image angle is s*theta + phi0 exactly, up to rounding of atan2 (and, for the
        # spherical mirror, its 1e-12 rad root tolerance, which does not affect the angle).
        np.testing.assert_allclose(_wrap(phi - (s * theta + phi0)), 0.0, atol=1e-12)
        _, directions = cam.trace(uv)
        az = np.arctan2(directions[:, 1], directions[:, 0])
        np.testing.assert_allclose(_wrap(az - theta), 0.0, atol=1e-9)


def test_project_returns_nan_where_unseen() -> None:
    par = standard_cameras(size=(200, 200))["parabolic"]
    assert np.isnan(par.project([0.0, 0.0, -1.0])).all()  # inside the 12 deg cut-off
    assert np.isnan(par.project([1.0, 0.0, 1.0])).all()  # 45 deg up: beyond the circle
    assert np.isnan(par.project([0.0, 0.0, 0.0])).all()  # O_m itself
    assert np.isfinite(par.project([1.0, 0.0, -1.0])).all()
    # The image rectangle clips the circle: a 200 x 100 image of a 94 px circle.
    wide = RadialCamera(
        name="w",
        law="equidistant",
        scale=94 / (95 * DEG),
        image_size=(200, 100),
        centre=(99.5, 49.5),
        alpha_max=95 * DEG,
    )
    assert np.isnan(wide.project([0.0, 1.0, -0.2])).all()  # lands near v = 49.5 + 80
    assert np.isfinite(wide.project([1.0, 0.0, -0.2])).all()  # lands near u = 99.5 + 80
    # Outside the circle; inside the circle but below the image; inside; the centre.
    origins, directions = wide.trace([[0.0, 0.0], [99.5, 120.0], [10.0, 49.5], [99.5, 49.5]])
    assert np.isnan(directions[:2]).all() and np.isnan(origins[:2]).all()
    assert np.isfinite(directions[2:]).all()
    np.testing.assert_allclose(directions[3], [0.0, 0.0, -1.0], atol=1e-15)


def test_radial_validation() -> None:
    base: dict[str, Any] = {"name": "x", "scale": 100.0, "image_size": (10, 10), "centre": (4.5, 4.5)}
    with pytest.raises(ValueError, match="law"):
        RadialCamera(law="stereo", alpha_max=1.0, **base)
    with pytest.raises(ValueError, match="increasing"):  # xi + cos(alpha_max) < 0
        RadialCamera(law="unified", xi=0.5, alpha_max=130 * DEG, **base)
    with pytest.raises(ValueError, match="increasing"):  # 1 + xi cos(alpha_max) < 0
        RadialCamera(law="unified", xi=2.0, alpha_max=125 * DEG, **base)
    with pytest.raises(ValueError, match="alpha_min"):
        RadialCamera(law="equidistant", alpha_min=1.0, alpha_max=0.5, **base)
    with pytest.raises(ValueError, match="s must"):
        RadialCamera(law="equidistant", alpha_max=1.0, s=0, **base)
    with pytest.raises(ValueError, match="xi"):
        RadialCamera(law="equisolid", xi=0.3, alpha_max=1.0, **base)
    with pytest.raises(ValueError, match="axis"):
        RadialCamera(law="equisolid", alpha_max=1.0, axis="side", **base)
    with pytest.raises(ValueError, match="pi/2"):  # sin(alpha) turns back beyond 90 deg
        RadialCamera(law="orthographic", alpha_max=1.6, **base)
    with pytest.raises(ValueError, match="increasing"):  # 1 - 0.3 alpha^2 turns back before alpha = 1.5
        RadialCamera(law="polynomial", distortion=(-0.1,), alpha_max=1.9, **base)
    with pytest.raises(ValueError, match="distortion"):
        RadialCamera(law="equidistant", distortion=(0.1,), alpha_max=1.0, **base)


def test_rho_radius_functions_are_inverse_and_nan_outside() -> None:
    for name in SVP_CAMERA_NAMES:
        cam = standard_cameras()[name]
        assert isinstance(cam, RadialCamera)
        low, high = cam.elevation_range
        rho = np.linspace(low, high, 501)
        r = cam.radius_of_rho(rho)
        assert np.all(np.diff(r) > 0)
        np.testing.assert_allclose(r[[0, -1]], [cam.cutoff_radius, cam.outer_radius], atol=1e-9)
        # Closed-form inverse: rounding error only.
        np.testing.assert_allclose(cam.rho_of_radius(r), rho, atol=1e-12)
        assert np.isnan(cam.radius_of_rho([low - 1e-6, high + 1e-6])).all()
        assert np.isnan(cam.rho_of_radius([cam.outer_radius + 1e-6])).all()


# ----------------------------------------------------------------------------------------
# Spherical mirror (no single viewpoint)
# ----------------------------------------------------------------------------------------


def test_spherical_round_trip_along_rays() -> None:
    cam = standard_cameras(size=(500, 500), seed=11)["spherical"]
    assert isinstance(cam, SphericalMirrorCamera)
    rng = np.random.default_rng(2024)
    uv = rng.uniform(0.0, 499.0, size=(4000, 2))
    r = np.hypot(uv[:, 0] - cam.centre[0], uv[:, 1] - cam.centre[1])
    uv = uv[(r > cam.cutoff_radius + 0.5) & (r < cam.outer_radius - 0.5)]
    assert len(uv) > 1500
    origins, directions = cam.trace(uv)
    np.testing.assert_allclose(np.linalg.norm(directions, axis=-1), 1.0, atol=1e-14)
    for distance in (0.5, 2.0, 10.0):
        back = cam.project(origins + distance * directions)
        # Bisection to 1e-12 rad in beta moves the pixel by focal*sec^2(beta)*1e-12, about
        # 1e-9 px; 1e-6 px leaves room for rounding in the residual near the root.
        np.testing.assert_allclose(back, uv, atol=1e-6, rtol=0)


def test_spherical_geometry() -> None:
    std = standard_cameras()["spherical"]
    assert isinstance(std, SphericalMirrorCamera)
    # With no cut-off, the image centre sees the camera itself: straight down.
    cam = SphericalMirrorCamera(
        name="sph",
        mirror_radius=std.mirror_radius,
        camera_distance=std.camera_distance,
        focal_px=std.focal_px,
        image_size=std.image_size,
        centre=std.centre,
        beta_min=0.0,
        beta_max=std.beta_max,
    )
    origins, directions = cam.trace([cam.centre])
    np.testing.assert_allclose(directions[0], [0.0, 0.0, -1.0], atol=1e-15)
    # The apex is viewpoint_offset below O_m.
    np.testing.assert_allclose(origins[0], [0.0, 0.0, -cam.viewpoint_offset], atol=1e-15)
    # The standard camera's cut-off hides the centre.
    assert np.isnan(std.trace([std.centre])[1]).all()
    # Elevation increases with the image radius, up to roughly +5..+15 deg at the rim.
    beta = np.linspace(std.beta_min, std.beta_max, 400)
    elevation = std.elevation_of_beta(beta)
    assert np.all(np.diff(elevation) > 0)
    assert 5 * DEG < std.elevation_range[1] < 15 * DEG
    assert std.elevation_range == pytest.approx((elevation[0], elevation[-1]), abs=1e-15)
    uv = np.stack([std.centre[0] + std.focal_px * np.tan(beta), np.full_like(beta, std.centre[1])], -1)
    _, directions = std.trace(uv)
    np.testing.assert_allclose(np.arcsin(directions[:, 2]), elevation, atol=1e-12)
    # No single viewpoint: the reflected lines miss O_m by several millimetres.
    distance = std.closest_approach(beta)
    assert distance.max() - distance.min() > 1e-3
    # Same from the traced rays: distance of O_m (the origin) to each line.
    origins, directions = std.trace(uv)
    miss = np.linalg.norm(np.cross(origins, directions), axis=-1)
    np.testing.assert_allclose(miss, distance, atol=1e-12)
    # O_m is the weighted least-squares point, inside the mirror's sphere above the apex.
    assert 0 < std.viewpoint_offset < std.mirror_radius


def test_spherical_nan_and_validation() -> None:
    cam = standard_cameras(size=(300, 300))["spherical"]
    assert np.isnan(cam.project([[0.0, 0.0, -2.0], [0.1, 0.0, 2.0], [0.0, 0.0, 0.0]])).all()
    assert np.isnan(cam.project([[np.nan, 0.0, 1.0]])).all()
    assert np.isnan(cam.trace([[0.0, 0.0]])[1]).all()  # image corner: beyond the rim
    with pytest.raises(ValueError, match="grazing"):
        SphericalMirrorCamera(
            name="x",
            mirror_radius=0.05,
            camera_distance=0.15,
            focal_px=100.0,
            image_size=(10, 10),
            centre=(4.5, 4.5),
            beta_min=0.0,
            beta_max=20 * DEG,
        )


# ----------------------------------------------------------------------------------------
# Standard set
# ----------------------------------------------------------------------------------------


def test_standard_cameras() -> None:
    cams = standard_cameras(size=(640, 480))
    assert list(cams) == [*SVP_CAMERA_NAMES, "spherical"]
    for name, cam in cams.items():
        assert isinstance(cam, SimulatedCamera)
        assert cam.name == name
        assert cam.image_size == (640, 480)
        assert cam.centre == (319.5, 239.5)
        assert cam.outer_radius == pytest.approx(0.47 * 480, rel=1e-12)
        assert cam.elevation_range[0] < cam.elevation_range[1]
    assert cams["equidistant"].cutoff_radius == 0.0
    assert cams["parabolic"].elevation_range == pytest.approx((-78 * DEG, 15 * DEG), abs=1e-12)
    assert cams["hyperbolic"].elevation_range == pytest.approx((-78 * DEG, 10 * DEG), abs=1e-12)
    moved = standard_cameras(size=(640, 480), centre=(300.0, 250.0))
    assert all(c.centre == (300.0, 250.0) for c in moved.values())
    a, b = standard_cameras(seed=5), standard_cameras(seed=5)
    assert all(a[n].centre == b[n].centre and a[n].phi0 == b[n].phi0 for n in a)
    assert a["equidistant"].centre != (479.5, 479.5)


# ----------------------------------------------------------------------------------------
# Room and renderer
# ----------------------------------------------------------------------------------------


def test_bundled_room_and_landmarks() -> None:
    room = load_room()
    assert (room.width, room.depth, room.height) == (6.0, 5.0, 2.6)
    assert room.camera == (3.1, 2.4, 2.45)
    names, points = room.landmarks()
    assert len(names) == len(set(names)) == points.shape[0] >= 24
    assert points.shape[1] == 3
    assert np.all(points >= 0) and np.all(points <= [6.0, 5.0, 2.6])
    d = points - np.array(room.camera)
    elevation = np.degrees(np.arctan2(d[:, 2], np.hypot(d[:, 0], d[:, 1])))
    azimuth = np.degrees(np.arctan2(d[:, 1], d[:, 0])) % 360
    # Spread over the elevation range and all around.
    for low, high in ((-90, -60), (-60, -35), (-35, -15), (-15, 0), (0, 5)):
        assert np.count_nonzero((elevation >= low) & (elevation < high)) >= 3, (low, high)
    assert np.all(np.histogram(azimuth, bins=8, range=(0, 360))[0] >= 2)
    door = names.index("W_door_bottom_left")
    np.testing.assert_allclose(points[door], [0.0, 3.4, 0.0])


def test_room_validation(tmp_path: Path) -> None:
    data = json.loads((resources.files("panomap") / "data" / "room.json").read_text(encoding="utf-8"))
    assert isinstance(Room.from_dict(data), Room)
    bad = dict(data, camera=[3.1, 2.4, 2.7])
    with pytest.raises(ValueError, match="inside"):
        Room.from_dict(bad)
    path = tmp_path / "room.json"
    path.write_text(json.dumps(dict(data, width=float("nan"))), encoding="utf-8")
    with pytest.raises(PanomapError, match="width must be finite") as info:
        load_room(path)
    assert info.value.source == str(path)  # the message names the file
    with pytest.raises(ValueError, match="format_version"):
        Room.from_dict(dict(data, format_version=2))


def test_render_shows_floor_checkerboard() -> None:
    room = load_room()
    cam = standard_cameras(size=(480, 480))["equidistant"]
    image = render(room, cam, supersample=2)
    assert image.shape == (480, 480, 3) and image.dtype == np.uint8
    # Tile centres: 0.25 m from the tile edges, far more than a pixel's footprint.
    xs = np.arange(0.25, room.width, room.tile_size)
    ys = np.arange(0.25, room.depth, room.tile_size)
    x, y = np.meshgrid(xs, ys)
    centres = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], axis=-1)
    uv = cam.project(centres - np.array(room.camera))
    seen = np.isfinite(uv[:, 0])
    assert seen.sum() == x.size  # the fisheye sees the whole floor
    pixels = image[np.rint(uv[:, 1]).astype(int), np.rint(uv[:, 0]).astype(int)]
    expected = room.floor_colour_at(centres[:, 0], centres[:, 1])
    # Every sub-pixel sample falls inside the tile, so the mean is the tile colour up to
    # float32 rounding before the final rint.
    np.testing.assert_allclose(pixels.astype(int), expected.astype(int), atol=1)
    assert len({tuple(p) for p in expected}) == 2
    # Outside the image circle (with one pixel of anti-aliasing margin) all is black.
    u, v = np.meshgrid(np.arange(480), np.arange(480))
    outside = np.hypot(u - cam.centre[0], v - cam.centre[1]) > cam.outer_radius + 1.0
    assert outside.any() and not image[outside].any()
    assert image[~outside].mean() > 50


@pytest.mark.parametrize("centre", [(200.0, 150.0), (201.37, 148.62)])
def test_a_field_stop_keeps_the_disc_and_its_area(centre: tuple[float, float]) -> None:
    """field_stop: black outside the rim's circle, untouched inside, and the disc's area (pi R^2, closed form)
    within 0.02% (each edge pixel keeps its coverage; measured 0.001-0.003%), wherever the centre falls."""
    radius = 120.4
    white = np.full((300, 400, 3), 255, dtype=np.uint8)
    stopped = field_stop(white, centre, radius)
    v, u = np.mgrid[0:300, 0:400]
    r = np.hypot(u - centre[0], v - centre[1])
    assert not stopped[r > radius + 0.71].any()
    assert (stopped[r < radius - 0.71] == 255).all()
    area = stopped[..., 0].astype(float).sum() / 255
    assert abs(area / (math.pi * radius**2) - 1) < 2e-4
    grey = field_stop(white[..., 0], centre, radius)
    assert grey.shape == (300, 400) and np.array_equal(grey, stopped[..., 0])
    with pytest.raises(PanomapError, match="radius"):
        field_stop(white, centre, 0.0)


def test_render_rays() -> None:
    room = load_room()
    o_m = np.array(room.camera)
    down = render_rays(room, o_m, [0.0, 0.0, -1.0])
    # (3.1, 2.4) lies 0.1 m from the nearest grid line: plain tile colour, exactly.
    np.testing.assert_array_equal(down, room.floor_colour_at(3.1, 2.4).astype(np.float32))
    up = render_rays(room, o_m, [0.0, 0.0, 1.0])
    np.testing.assert_array_equal(up, np.array(room.ceiling_colour_bgr, np.float32))
    # The rail line (1.0 m) and a window pane on the north wall (y = 5).
    north = render_rays(
        room, [[4.0, 2.0, 1.0], [2.0, 2.0, 1.0]], [[0.0, 1.0, 0.0], [-0.1, 1.0, 0.2]]
    )  # hits (4.0, 5, 1.0) and (1.7, 5, 1.6), 0.1 m from the window's mullions
    np.testing.assert_array_equal(north[0], np.array(room.line_colour_bgr, np.float32))
    np.testing.assert_array_equal(north[1], np.array(room.window_colour_bgr, np.float32))
    # NaN or zero directions give 0; shapes broadcast.
    out = render_rays(room, o_m, [[np.nan, 0.0, 1.0], [0.0, 0.0, 0.0]])
    assert out.shape == (2, 3) and out.dtype == np.float32 and not out.any()
    with pytest.raises(ValueError, match="inside"):
        render_rays(room, [7.0, 1.0, 1.0], [1.0, 0.0, 0.0])


def test_a_housed_mirror_whose_rim_is_outside_the_frame_keeps_the_mirror_image() -> None:
    """A rim wholly past the frame (a mirror image that fills it): the frame is the mirror, left as it was away
    from the camera's own board; the housing's level came from the rim's ring, absent here, and was NaN (the
    whole image turned to garbage)."""
    from panomap.simulate import housed_mirror

    rng = np.random.default_rng(3)
    image = rng.integers(40, 200, size=(120, 160, 3), dtype=np.uint8)
    image[:] = image[..., :1]  # grey, so that the BGR round trip keeps it exactly
    housed = housed_mirror(image, (79.5, 59.5), 130.0, 10.0, np.random.default_rng(4))
    v, u = np.mgrid[0:120, 0:160]
    away = np.hypot(u - 79.5, v - 59.5) > 35.0  # past the board (half side at most twice the disc's radius, turned)
    assert np.array_equal(housed[away], image[away])


def test_a_housed_mirror_shows_its_picture_up_to_the_rim() -> None:
    """Where the housing is as bright as the mirror (a faint arc), the level runs on across the rim: no dark band.

    The mirror's picture stops at the rim with an edge of its own (its pixels there half
    covered, black beyond); composited under the housing's edge as it was, each rim pixel
    was darkened twice: a band under a pixel wide, which real mirrors do not have and which
    the circle search then took for the rim on its faint arcs. With the rim faint on 97% of
    it, the 10th percentile of the rim's pixels was 92-101 for a mirror at 128 (three
    seeds); exact, 119-128: the housing's rings (15 grey levels, blurred) are all that differ.
    """
    from panomap.simulate import housed_mirror

    size, centre, radius, level = 240, (119.5, 119.5), 100.0, 128.0
    v, u = np.mgrid[0:size, 0:size]
    r = np.hypot(u - centre[0], v - centre[1])
    mirror = level * np.clip(radius - r + 0.5, 0.0, 1.0)  # a uniform mirror with its own anti-aliased edge
    image = np.repeat(np.rint(mirror).astype(np.uint8)[..., None], 3, axis=2)
    on_rim = np.abs(r - radius) < 1.0
    for seed in range(3):
        housed = housed_mirror(image, centre, radius, 20.0, np.random.default_rng(seed), faint=0.97)
        assert np.percentile(housed[..., 0][on_rim], 10) >= level - 12.0, seed
