"""The boards' least squares on block normal equations (panomap.calibrate.boards.solve) against dense linear algebra."""

from __future__ import annotations

import numpy as np

from panomap.calibrate.boards.solve import BlockJacobian, Normal, least_squares_blocks, soft_l1


def _blocks(seed: int, count: int = 3, rows: tuple[int, ...] = (8, 14, 10, 12)) -> BlockJacobian:
    """A random Jacobian of ``count`` camera columns and one board per entry of ``rows`` (its rows)."""
    rng = np.random.default_rng(seed)
    owner = np.repeat(np.arange(len(rows)), rows)
    return BlockJacobian(rng.normal(size=(len(owner), count + 6)), owner, count, len(rows))


def test_the_schur_step_is_the_dense_damped_solve() -> None:
    jacobian = _blocks(1)
    residuals = np.random.default_rng(2).normal(size=len(jacobian.owner))
    dense = jacobian.dense()
    normal = dense.T @ dense
    for damping in (1e-6, 1e-2, 10.0):
        expected = -np.linalg.solve(normal + damping * np.diag(np.diag(normal)), dense.T @ residuals)
        camera, poses = Normal.of(jacobian, residuals).step(damping)
        assert np.allclose(np.concatenate([camera, poses.ravel()]), expected, rtol=1e-9, atol=1e-12)
    # the camera held: the poses' step alone, each board's own
    held = jacobian.poses_only()
    camera, poses = Normal.of(held, residuals).step(1e-3)
    dense = held.dense()
    normal = dense.T @ dense
    expected = -np.linalg.solve(normal + 1e-3 * np.diag(np.diag(normal)), dense.T @ residuals)
    assert camera.size == 0 and np.allclose(poses.ravel(), expected, rtol=1e-9, atol=1e-12)


def test_the_normal_equations_taken_size_by_size_are_each_boards_own_products() -> None:
    """The boards' rows' products taken in one batched call per size of board (two sizes of two boards, one of
    one): the blocks of the dense J^T J and J^T r, and the same values, bit for bit, as each board's own product."""
    rows = (10, 12, 10, 12, 7)
    jacobian = _blocks(7, rows=rows)
    residuals = np.random.default_rng(8).normal(size=len(jacobian.owner))
    normal = Normal.of(jacobian, residuals)
    dense = jacobian.dense()
    c = jacobian.count
    product, gradient = dense.T @ dense, dense.T @ residuals
    np.testing.assert_allclose(normal.camera, product[:c, :c], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(normal.camera_gradient, gradient[:c], rtol=1e-12, atol=1e-12)
    own = [(jacobian.values[jacobian.owner == b], residuals[jacobian.owner == b]) for b in range(len(rows))]
    np.testing.assert_array_equal(normal.camera, np.sum([(v.T @ v)[:c, :c] for v, _ in own], axis=0))
    for board, (values, board_residuals) in enumerate(own):
        columns = slice(c + 6 * board, c + 6 * board + 6)
        np.testing.assert_allclose(normal.poses[board], product[columns, columns], rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(normal.cross[board], product[:c, columns], rtol=1e-12, atol=1e-12)
        np.testing.assert_array_equal(normal.poses[board], (values.T @ values)[c:, c:])
        np.testing.assert_array_equal(normal.cross[board], (values.T @ values)[:c, c:])
        np.testing.assert_array_equal(normal.pose_gradient[board], (values.T @ board_residuals)[c:])


def test_the_steps_end_at_the_least_squares_solution_of_a_linear_problem() -> None:
    jacobian = _blocks(3)
    dense = jacobian.dense()
    target = np.random.default_rng(4).normal(size=len(dense))
    solution = least_squares_blocks(
        lambda x: dense @ x - target, lambda x: jacobian, np.zeros(dense.shape[1]), 50, 1e-12
    )
    expected = np.linalg.lstsq(dense, target, rcond=None)[0]
    assert np.max(np.abs(solution.x - expected)) < 1e-8
    assert np.allclose(solution.residuals, dense @ solution.x - target)


def test_the_robust_reweighting_gives_the_soft_l1_cost_s_gradient() -> None:
    jacobian = _blocks(5)
    dense = jacobian.dense()
    rng = np.random.default_rng(6)
    target, x = rng.normal(size=len(dense)) * 4.0, rng.normal(size=dense.shape[1])
    _, reweighted, weights = soft_l1(dense @ x - target, 2.0)
    gradient = 2.0 * (dense * weights[:, None]).T @ reweighted
    step = 1e-6
    numeric = [
        (soft_l1(dense @ (x + step * e) - target, 2.0)[0] - soft_l1(dense @ (x - step * e) - target, 2.0)[0])
        / (2 * step)
        for e in np.eye(len(x))
    ]
    assert np.allclose(gradient, numeric, rtol=1e-6, atol=1e-6)
