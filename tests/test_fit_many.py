"""Many landmarks (a checkerboard, a surveyed room): k-fold cross-validation above EXACT_LOO_MAX.

Ground truth: the scenarios' simulated cameras (closed-form projection). The
cost is measured by bench/bench_fit_count.py, not here.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from panomap.calibrate.core import noise, selection, start
from panomap.calibrate.core.selection import CV_FOLDS, EXACT_LOO_MAX
from panomap.calibrate.landmarks.fit import fit_camera
from panomap.calibrate.landmarks.pairs import Landmarks
from panomap.camera.radial import fit_radial
from panomap.camera.radial_models import radial_kind
from panomap.geometry import azimuth_elevation, pixel_polar
from panomap.simulate import scenarios
from panomap.simulate.sampling import LandmarkPairs
from panomap.simulate.scenarios import CAMERA_POSITION, IMAGE_SIZE, Trial, make_landmarks, scenario_cameras

from helpers import worst_error

COUNT = 300


@pytest.mark.parametrize("name", ["equisolid", "hyperbolic-0.9"])
def test_many_landmarks_flag_every_outlier_and_fit_the_camera(name: str) -> None:
    camera = scenario_cameras()[name]
    rng = np.random.default_rng(7)
    trial = make_landmarks(camera, COUNT, rng, spread=False)
    pixels = np.array(trial.landmarks.pixels, dtype=np.float64)
    bad = rng.choice(COUNT, 15, replace=False)
    pixels[bad] += 50.0 * np.array([0.6, 0.8])
    landmarks = Landmarks(pixels, trial.landmarks.world, trial.landmarks.names)
    fit = fit_camera(landmarks, CAMERA_POSITION, camera.centre, image_size=IMAGE_SIZE)
    flagged = set(fit.outliers)
    # Every 50 px landmark goes, and (1 px / 1 cm noise) no good one: 5 sigmas is far out.
    assert flagged == {landmarks.names[k] for k in bad}
    error = worst_error(
        camera,
        Trial(LandmarkPairs(pixels, trial.landmarks.world, trial.landmarks.names)),
        scenarios.test_points(camera),
    )
    # Measured 0.57 (equisolid) and 0.53 px (hyperbolic) over the test points with 285 good landmarks.
    assert error < 1.5


def test_kfold_is_used_above_the_bound_and_chooses_as_exact_leave_one_out() -> None:
    """Above EXACT_LOO_MAX the folds are CV_FOLDS; on the same data both choose the same model."""
    camera = scenario_cameras()["parabolic"]
    trial = make_landmarks(camera, EXACT_LOO_MAX + 20, np.random.default_rng(3))
    landmarks = Landmarks(*trial.landmarks)
    kfold = fit_camera(landmarks, CAMERA_POSITION, camera.centre, image_size=IMAGE_SIZE)
    saved = selection.EXACT_LOO_MAX
    selection.EXACT_LOO_MAX = 10**9
    try:
        exact = fit_camera(landmarks, CAMERA_POSITION, camera.centre, image_size=IMAGE_SIZE)
    finally:
        selection.EXACT_LOO_MAX = saved
    # (The parabolic law is the unified model's xi = 1 and the fisheye family's k = -1/2: either may win.)
    assert kfold.model.radial.kind == exact.model.radial.kind in ("unified", "fisheye")
    assert CV_FOLDS < landmarks.pixels.shape[0]
    # Same model, same inliers: the refined fits agree to rounding.
    np.testing.assert_allclose(kfold.predicted, exact.predicted, atol=1e-6)


def test_a_fit_kept_with_the_data_is_the_fit_of_those_data() -> None:
    """Each subset's fit is made once and kept with the data it was made on: the same subset of other
    data (the centre moved: other radii) is fitted afresh, never served from the first data's fits."""
    camera = scenario_cameras()["equisolid"]
    trial = make_landmarks(camera, 12, np.random.default_rng(5))
    landmarks = Landmarks(*trial.landmarks)
    fit = fit_camera(landmarks, CAMERA_POSITION, camera.centre, image_size=IMAGE_SIZE)
    kind = radial_kind(fit.model.radial.kind)
    d = landmarks.world - np.asarray(CAMERA_POSITION)
    theta, rho = azimuth_elevation(d)
    data = noise.Observations(
        theta, rho, np.zeros(12), np.zeros(12), np.full(12, 0.01), np.full(12, 0.01), 1.0, "down", 1, "fit"
    )
    subset = np.ones(12, dtype=bool)
    for shift in (0.0, 7.0):  # the same subset, two centres 7 px apart
        r, phi = pixel_polar(landmarks.pixels, (camera.centre[0] + shift, camera.centre[1]))
        moved = replace(data, r=r, phi=phi)
        kept, _ = start.separable_fit(kind, moved, subset)
        assert start.separable_fit(kind, moved, subset)[0] is kept  # asked again: the fit kept
        fresh = fit_radial(kind.name, rho, r, "down")
        for _ in range(start.WEIGHT_ITERATIONS):
            fresh = fit_radial(kind.name, rho, r, "down", noise.radial_weights(fresh, moved))
        # Exactly the fit of these data: the radii 7 px apart give coefficients far apart.
        np.testing.assert_allclose(kept.coefficients, fresh.coefficients, rtol=1e-12)
