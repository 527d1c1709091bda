"""A landmark a pixel or two past the image circle (measurement noise at the rim) is kept, not refused.

Ground truth: the simulated hyperbolic camera's closed-form projection.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from panomap.calibrate.core.noise import RIM_SLACK_SIGMAS
from panomap.calibrate.landmarks.fit import fit_camera
from panomap.calibrate.landmarks.pairs import Landmarks
from panomap.calibrate.landmarks.pipeline import calibrate_camera
from panomap.camera.radial import RadialFunction
from panomap.camera.valid_range import valid_elevation_range
from panomap.errors import PanomapError
from panomap.geometry import ray_from_angles
from panomap.simulate import standard_cameras
from panomap.simulate.cameras import RadialCamera
from panomap.simulate.scenarios import CAMERA_POSITION, IMAGE_SIZE, make_landmarks
from panomap.simulate.scenarios import test_points as probe_points

from helpers import spread_landmarks, worst_error

SIZE = (800, 760)
POSITION = (3.0, 2.0, 2.5)
CAMERA = standard_cameras(SIZE, centre=(401.3, 379.6), s=-1, phi0=0.7)["hyperbolic"]


def landmarks_with_one_at_the_rim(outward_px: float) -> Landmarks:
    """Eleven spread landmarks, and a twelfth whose true pixel is 0.5 px inside the image circle, moved outward."""
    inner = spread_landmarks(CAMERA, POSITION, 11, np.random.default_rng(2))
    # The elevation whose true radius is the circle's less 0.5 px, by bisection on the closed form.
    azimuth = 1.1
    low, high = -1.5, CAMERA.elevation_range[1]
    for _ in range(60):
        middle = 0.5 * (low + high)
        ray = 2.0 * ray_from_angles(azimuth, middle)  # relative to the camera, as project takes it
        radius = float(np.hypot(*(CAMERA.project(ray[None])[0] - CAMERA.centre)))
        low, high = (middle, high) if radius < CAMERA.outer_radius - 0.5 else (low, middle)
    pixel = CAMERA.project(ray[None])[0]
    point = np.asarray(POSITION) + ray
    direction = (pixel - CAMERA.centre) / np.linalg.norm(pixel - CAMERA.centre)
    moved = pixel + outward_px * direction
    return Landmarks(np.vstack([inner.pixels, moved]), np.vstack([inner.world, point]), (*inner.names, "rim"))


def test_a_landmark_just_past_the_rim_is_kept_with_a_note() -> None:
    landmarks = landmarks_with_one_at_the_rim(2.3)  # 1.8 px beyond the circle, as in the issue
    result = calibrate_camera(
        landmarks,
        POSITION,
        centre=CAMERA.centre,
        cutoff_radius=CAMERA.cutoff_radius,
        outer_radius=CAMERA.outer_radius,
        image_size=SIZE,
    )
    assert "rim" not in result.fit.outliers
    notes = [w for w in result.table.info["warnings"] if "beyond the image circle" in w]
    assert len(notes) == 1 and "'rim'" in notes[0] and "kept" in notes[0]
    table = result.table
    # The table reaches the landmark (the camera sees its direction), a little past the circle: its last
    # elevation is the landmark's, where the fit puts it within the slack beyond the circle.
    top = table.model.pixels(0.0, table.elevation_range[1])
    beyond = np.hypot(*(top - np.asarray(CAMERA.centre))) - CAMERA.outer_radius
    assert 0.0 < beyond <= RIM_SLACK_SIGMAS * 1.0
    assert table.elevation_range[1] == pytest.approx(result.fit.landmark_range[1], abs=1e-9)
    # And the table is still the camera: test points inside the circle land within a few px of the truth.
    rho = np.linspace(table.elevation_range[0] + 0.01, table.elevation_range[1] - 0.01, 30)
    theta = np.linspace(0.0, 2 * np.pi, 30, endpoint=False)
    t, r = (a.ravel() for a in np.meshgrid(theta, rho))
    rays = 2.0 * ray_from_angles(t, r)
    error = np.linalg.norm(table.project(np.asarray(POSITION) + rays) - CAMERA.project(rays), axis=1)
    # Measured 0.72 px worst with that landmark pulled 2.3 px (the others exact).
    assert np.nanmax(error) < 2.5 and not np.isnan(error).any()


@pytest.mark.parametrize("beyond_px", [2.0, 4.0])
def test_the_range_reaches_a_landmark_within_the_slack_and_refuses_beyond(beyond_px: float) -> None:
    """Closed form: r = 300 alpha (alpha from the nadir); the highest landmark ``beyond_px`` past R = 450."""
    radial = RadialFunction("odd1", (300.0,), "down")
    outer = 450.0
    high = (outer + beyond_px) / 300.0 - np.pi / 2  # the landmark's elevation: r(high) = outer + beyond_px
    low = 100.0 / 300.0 - np.pi / 2
    slack = RIM_SLACK_SIGMAS * 1.0
    if beyond_px > slack:
        with pytest.raises(PanomapError, match="outside the annulus"):
            valid_elevation_range(radial, (low, high), 50.0, outer, slack_px=slack)
        return
    rho_s, rho_e = valid_elevation_range(radial, (low, high), 50.0, outer, slack_px=slack)
    assert rho_e == high  # the landmark's elevation: not where r reaches R, nor a grid step beyond
    assert rho_s == pytest.approx(50.0 / 300.0 - np.pi / 2, abs=1e-12)  # and down to the cut-off
    with pytest.raises(PanomapError, match="outside the annulus"):  # without the slack: refused, as before
        valid_elevation_range(radial, (low, high), 50.0, outer)


# An orthographic fisheye (r = f sin(alpha), 176 deg): its law flattens at the rim, where a pixel spans a degree.
ORTHOGRAPHIC = RadialCamera(
    name="orthographic",
    law="orthographic",
    scale=0.47 * IMAGE_SIZE[0] / math.sin(math.radians(88.0)),
    image_size=IMAGE_SIZE,
    centre=((IMAGE_SIZE[0] - 1) / 2, (IMAGE_SIZE[1] - 1) / 2),
    alpha_max=math.radians(88.0),
)


@pytest.mark.parametrize("seed", [13007, 16007])
def test_a_lens_whose_law_flattens_at_the_rim_covers_the_view(seed: int) -> None:
    """Ten landmarks spread in elevation, 1 px and 1 cm of noise. Before: seed 13007's joint refinement moved
    `fisheye`'s k past 1 and turned the curve back 1 px short of the circle (the table refused it; so did 3
    more of 50 seeds); seed 16007's top landmark, 2 deg below the rim and good, was dropped as an outlier
    (5.1 sigmas held out, whitened by its noise alone; 2.4 with the others' prediction error) and the
    table stopped 1 deg short of the test points."""
    trial = make_landmarks(ORTHOGRAPHIC, 10, np.random.default_rng(seed))
    fit = fit_camera(
        Landmarks(*trial.landmarks),
        CAMERA_POSITION,
        ORTHOGRAPHIC.centre,
        image_size=IMAGE_SIZE,
        annulus=(ORTHOGRAPHIC.cutoff_radius, ORTHOGRAPHIC.outer_radius),
    )
    assert fit.outliers == []
    # Measured 4.02 and 1.13 px (worst over the test points; 50 seeds: all but 13007 under 3.5 px).
    assert worst_error(ORTHOGRAPHIC, trial, probe_points(ORTHOGRAPHIC)) < 6.0
