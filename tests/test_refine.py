"""The refinement's residual blocks (calibrate/core/refine.py): a block adds its own unknowns and residuals.

Ground truth: a block whose residuals are written here in closed form, ``(a - A) / SIGMA`` for its one
unknown ``a``: its least-squares value is A, its variance SIGMA^2 (it shares no residual with the camera's
unknowns), and the camera refined with it is the camera refined without it.
"""

from __future__ import annotations

import numpy as np

from panomap.calibrate.core.refine import MountOptions, MountProblem, MountSolution, refine
from panomap.calibrate.landmarks.fit import fit_camera
from panomap.simulate.cameras import standard_cameras

from helpers import spread_landmarks

POSITION = (0.0, 0.0, 2.5)
A, SIGMA = 3.0, 0.5


class OffsetBlock:
    """One unknown of its own, ``a``, and one residual ``(a - A) / SIGMA``."""

    unknowns = 1

    def start(self) -> np.ndarray:
        return np.array([0.0])

    def residuals(self, camera: MountSolution, own: np.ndarray) -> np.ndarray:
        assert own.shape == (1,) and camera.covariance.shape == (0, 0)
        return (own - A) / SIGMA


def test_a_block_adds_its_unknowns_and_residuals() -> None:
    base = standard_cameras(seed=3)["equidistant"]
    landmarks = spread_landmarks(base, POSITION, 12, np.random.default_rng(6))
    fit = fit_camera(landmarks, POSITION, base.centre, tilt_deg="none", camera_sigma=0.0)
    problem = MountProblem(
        world=landmarks.world, pixels=landmarks.pixels, camera=np.asarray(POSITION), kind=fit.model.radial.kind,
        axis=fit.model.axis, s=fit.model.s, pixel_sigma=1.0, world_sigma=0.01, camera_sigma=0.02,
    )  # fmt: skip
    # Started off the fit (the centre 2 px away), the centre refined with the camera's tilt.
    start = MountSolution(
        fit.model.radial, fit.model.phi0, (fit.model.centre[0] + 2.0, fit.model.centre[1]), np.zeros(2), np.zeros(3),
        np.empty((0, 0)),
    )  # fmt: skip
    subset = np.ones(len(landmarks), dtype=bool)
    options = MountOptions(centre=True, tilt=True)
    alone = refine(problem, start, subset, options)
    with_block = refine(problem, start, subset, options, blocks=(OffsetBlock(),))
    (own,) = with_block.own
    np.testing.assert_allclose(own, [A], atol=1e-6)
    count = len(fit.model.radial.coefficients) + 1 + 2 + 2  # coefficients, phi0, centre, tilt: then the block's
    assert with_block.covariance.shape == (count + 1, count + 1)
    np.testing.assert_allclose(with_block.covariance[count, count], SIGMA**2, rtol=1e-6)
    np.testing.assert_allclose(with_block.covariance[count, :count], 0.0, atol=1e-9)
    # The camera's unknowns are untouched by an independent block: same centre, tilt and their covariance.
    np.testing.assert_allclose(with_block.solution.centre, alone.solution.centre, atol=1e-6)
    np.testing.assert_allclose(with_block.solution.w, alone.solution.w, atol=1e-9)
    np.testing.assert_allclose(with_block.covariance[:count, :count], alone.covariance, rtol=1e-4, atol=1e-12)
    # Exact landmarks of a level camera: the centre comes back from 2 px off, and no tilt.
    assert np.hypot(*np.subtract(alone.solution.centre, fit.model.centre)) < 0.01
    assert np.hypot(*alone.solution.w) < 1e-5
