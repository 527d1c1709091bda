"""Many landmarks (a checkerboard, a surveyed room): k-fold cross-validation above EXACT_LOO_MAX.

Ground truth: the scenarios' simulated cameras (closed-form projection). The
cost is measured by bench/bench_fit_count.py, not here.
"""

from __future__ import annotations

import numpy as np
import pytest

from panomap.calibrate import fit as fit_module
from panomap.calibrate.fit import CV_FOLDS, EXACT_LOO_MAX, fit_camera
from panomap.calibrate.landmarks import Landmarks
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
    saved = fit_module.EXACT_LOO_MAX
    fit_module.EXACT_LOO_MAX = 10**9
    try:
        exact = fit_camera(landmarks, CAMERA_POSITION, camera.centre, image_size=IMAGE_SIZE)
    finally:
        fit_module.EXACT_LOO_MAX = saved
    # (The parabolic law is the unified model's xi = 1 and the fisheye family's k = -1/2: either may win.)
    assert kfold.model.radial.kind == exact.model.radial.kind in ("unified", "fisheye")
    assert CV_FOLDS < landmarks.pixels.shape[0]
    # Same model, same inliers: the refined fits agree to rounding.
    np.testing.assert_allclose(kfold.predicted, exact.predicted, atol=1e-6)
