"""The boards' least squares: damped Gauss-Newton (Levenberg-Marquardt) steps on block normal equations.

Convention: the unknowns are the camera's ``count`` parameters, then six per board (its pose); each residual
row sees the camera and its own board's pose only, rows grouped board by board in order (as :mod:`.fit` builds
them). So the normal equations ``J^T J`` are a camera block C (count, count), one (count, 6) block W_b and one
(6, 6) block V_b per board, and a step is solved through the Schur complement: every board's damped V_b
inverted in one batched call, the camera's system ``C - sum_b W_b V_b^-1 W_b^T`` solved, the poses' steps from
it. Each board's blocks are one small product of its rows (the boards of each size in one batched product,
the same values): a fraction of a millisecond a step, where SciPy's
trust-region solver with LSMR steps spent most of the fit in its Python overhead.

The steps: Marquardt's, the damping ``lambda`` times the normal equations' diagonal, updated as Nielsen's
(after a step that lowers the cost, lambda times ``max(1/3, 1 - (2 g - 1)^3)``, g the drop over the drop the
linear model predicts; after one that does not, times 2, 4, 8, ... until one does); it stops when a step lowers
the cost by no more than ``tolerance`` of it, after ``steps`` steps or ``evaluations`` evaluations of the
residuals, or when no step lowers it (lambda past ``MAX_DAMPING``: the minimum to rounding). (Dividing lambda
by 10 after every step, from a start 5 px RMS off, refused every other step and left it far off after the 40
evaluations a start may take.) A robust loss (SciPy's ``soft_l1``, scale ``f_scale``) is
minimised by the same steps on residuals and rows reweighted at each step as SciPy does.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import csr_matrix

from ...geometry import FloatArray

# The damping at the start (near the minimum, from a fit close to it) and its floor, and where the steps give up
# (no step lowers the cost).
NEAR_DAMPING = 1e-6
MIN_DAMPING = 1e-9
MAX_DAMPING = 1e6
# A weight (SciPy's floor) below which a robust loss's reweighting is not taken.
_LEAST_WEIGHT = np.finfo(np.float64).eps


@dataclass(frozen=True)
class BlockJacobian:
    """A Jacobian (R, count + 6 B) whose row r holds ``values[r]`` (R, count + 6): the camera's ``count``
    columns, then the six pose columns of its board ``owner[r]`` (R,), rows in order of their boards (every
    board of the ``boards`` with a row)."""

    values: FloatArray
    owner: NDArray[np.intp]
    count: int
    boards: int

    def sparse(self) -> csr_matrix:
        """The Jacobian as a sparse matrix (R, count + 6 B)."""
        rows, count = len(self.values), self.count
        columns = np.concatenate(
            [np.broadcast_to(np.arange(count), (rows, count)), (count + 6 * self.owner)[:, None] + np.arange(6)],
            axis=1,
        )
        pointers = np.arange(rows + 1) * (count + 6)
        return csr_matrix((self.values.ravel(), columns.ravel(), pointers), shape=(rows, count + 6 * self.boards))

    def dense(self) -> FloatArray:
        """The Jacobian as an array (R, count + 6 B)."""
        return np.asarray(self.sparse().toarray(), dtype=np.float64)

    def poses_only(self) -> BlockJacobian:
        """The Jacobian in the poses alone (the camera held)."""
        return BlockJacobian(self.values[:, self.count :], self.owner, 0, self.boards)

    def weighted(self, weights: FloatArray) -> BlockJacobian:
        """The rows times ``weights`` (R,)."""
        return BlockJacobian(self.values * weights[:, None], self.owner, self.count, self.boards)


@dataclass(frozen=True)
class Normal:
    """The normal equations ``J^T J x = J^T r`` of a :class:`BlockJacobian` in blocks: the camera's C (c, c),
    the boards' W (B, c, 6) and V (B, 6, 6), the gradient's camera part (c,) and pose parts (B, 6)."""

    camera: FloatArray
    cross: FloatArray
    poses: FloatArray
    camera_gradient: FloatArray
    pose_gradient: FloatArray

    @classmethod
    def of(cls, jacobian: BlockJacobian, residuals: FloatArray) -> Normal:
        values, c = jacobian.values, jacobian.count
        first = np.flatnonzero(np.concatenate([[True], jacobian.owner[1:] != jacobian.owner[:-1]]))
        if len(first) != jacobian.boards:
            raise ValueError("the Jacobian's rows are not grouped board by board, every board with rows")
        # each board's products (B, c + 6, c + 6) and (B, c + 6), the boards of each size in one batched call (a
        # fifth of the time of one call a board; the same values)
        counts = np.diff(np.append(first, len(values)))
        sums = np.empty((len(first), values.shape[1], values.shape[1]))
        gradients = np.empty((len(first), values.shape[1]))
        for size in np.unique(counts):
            these = np.flatnonzero(counts == size)
            rows = (first[these][:, None] + np.arange(size)).ravel()
            blocks = values[rows].reshape(len(these), size, values.shape[1])
            turned = blocks.transpose(0, 2, 1)
            sums[these] = np.matmul(turned, blocks)
            gradients[these] = np.matmul(turned, residuals[rows].reshape(len(these), size, 1))[:, :, 0]
        camera, cross, poses = sums[:, :c, :c].sum(axis=0), sums[:, :c, c:], sums[:, c:, c:]
        return cls(camera, cross, poses, gradients[:, :c].sum(axis=0), gradients[:, c:])

    def diagonal(self) -> tuple[FloatArray, FloatArray]:
        """The damping's scale, D: the diagonals of the camera's block (c,) and of the boards' (B, 6), 1 where a
        column is zero."""
        camera, poses = np.diagonal(self.camera).copy(), np.diagonal(self.poses, axis1=1, axis2=2).copy()
        camera[camera == 0] = 1.0
        poses[poses == 0] = 1.0
        return camera, poses

    def step(self, damping: float) -> tuple[FloatArray, FloatArray]:
        """The damped Gauss-Newton step (the camera's (c,), the poses' (B, 6)): ``(J^T J + damping D) x = -J^T r``,
        D the diagonal of J^T J (1 where a column is zero). Raises ``np.linalg.LinAlgError`` where singular."""
        camera_diagonal, pose_diagonal = self.diagonal()
        poses = self.poses + damping * pose_diagonal[:, :, None] * np.eye(6)
        inverse = np.linalg.inv(poses)  # (B, 6, 6), every board at once
        if self.camera.size == 0:
            return np.zeros(0), -np.einsum("bij,bj->bi", inverse, self.pose_gradient)
        across = np.einsum("bcj,bjk->bck", self.cross, inverse)  # W_b V_b^-1 (B, c, 6)
        schur = self.camera + damping * np.diag(camera_diagonal) - np.einsum("bck,bdk->cd", across, self.cross)
        right = self.camera_gradient - np.einsum("bck,bk->c", across, self.pose_gradient)
        camera_step = -np.linalg.solve(schur, right)
        pose_step = -np.einsum(
            "bij,bj->bi", inverse, self.pose_gradient + np.einsum("bcj,c->bj", self.cross, camera_step)
        )
        return camera_step, pose_step

    def predicted_drop(self, camera_step: FloatArray, pose_step: FloatArray, damping: float) -> float:
        """The drop of the cost (the squares' sum) the linear model predicts for a step :meth:`step` gave."""
        camera_diagonal, pose_diagonal = self.diagonal()
        damped = float(camera_step @ (camera_diagonal * camera_step) + np.sum(pose_step * pose_diagonal * pose_step))
        along = float(camera_step @ self.camera_gradient + np.sum(pose_step * self.pose_gradient))
        return damping * damped - along


@dataclass(frozen=True)
class Solution:
    """Where the steps ended: the unknowns (P,), the residuals there (R,), and the evaluations of the residuals
    they took."""

    x: FloatArray
    residuals: FloatArray
    evaluations: int


def soft_l1(residuals: FloatArray, scale: float) -> tuple[float, FloatArray, FloatArray]:
    """SciPy's ``soft_l1`` loss of ``residuals`` (R,) at ``scale``: its cost (twice SciPy's), the residuals
    reweighted for a Gauss-Newton step and the rows' weights (R,) (SciPy's ``scale_for_robust_loss_function``)."""
    z = (residuals / scale) ** 2
    first = 1.0 / np.sqrt(1.0 + z)
    second = -0.5 * first**3
    cost = float(2.0 * scale**2 * np.sum(np.sqrt(1.0 + z) - 1.0))
    weights = np.maximum(first + 2.0 * second * z, _LEAST_WEIGHT)
    return cost, residuals * first / np.sqrt(weights), np.sqrt(weights)


def least_squares_blocks(
    fun: Callable[[FloatArray], FloatArray],
    jac: Callable[[FloatArray], BlockJacobian],
    x0: FloatArray,
    steps: int,
    tolerance: float,
    evaluations: int | None = None,
    robust_scale: float | None = None,
    damping: float = NEAR_DAMPING,
) -> Solution:
    """The least-squares minimum of ``fun`` (residuals (R,) of the unknowns (P,)) near ``x0`` by the damped
    Gauss-Newton steps above, ``jac`` its :class:`BlockJacobian`; ``robust_scale``: the soft_l1 loss at that
    scale (px) instead of the squares; ``damping``: the damping to start from. Raises ``np.linalg.LinAlgError``
    where the normal equations are singular."""
    x = np.asarray(x0, dtype=np.float64).copy()
    r = fun(x)
    used = 1

    def cost_of(residuals: FloatArray) -> float:
        if robust_scale is None:
            return float(residuals @ residuals)
        return soft_l1(residuals, robust_scale)[0]

    cost = cost_of(r)
    growth = 2.0
    for _ in range(steps):
        if evaluations is not None and used >= evaluations:
            break
        jacobian = jac(x)
        if robust_scale is None:
            normal = Normal.of(jacobian, r)
        else:
            _, reweighted, weights = soft_l1(r, robust_scale)
            normal = Normal.of(jacobian.weighted(weights), reweighted)
        while True:
            camera_step, pose_step = normal.step(damping)
            trial = x + np.concatenate([camera_step, pose_step.ravel()])
            r_trial = fun(trial)
            used += 1
            trial_cost = cost_of(r_trial)
            if math.isfinite(trial_cost) and trial_cost <= cost:
                break
            damping *= growth
            growth *= 2.0
            if damping > MAX_DAMPING or (evaluations is not None and used >= evaluations):
                return Solution(x, r, used)  # no step lowers the cost: x is the minimum to rounding
        predicted = normal.predicted_drop(camera_step, pose_step, damping)
        ratio = (cost - trial_cost) / predicted if predicted > 0 else 0.0
        drop = cost - trial_cost
        x, r, cost = trial, r_trial, trial_cost
        damping = max(damping * max(1.0 / 3.0, 1.0 - (2.0 * ratio - 1.0) ** 3), MIN_DAMPING)
        growth = 2.0
        if drop <= tolerance * cost:
            break
    return Solution(x, r, used)
