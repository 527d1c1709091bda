"""Circles and ellipses fitted to edge points (N, 2) [u, v] px: algebraic, consensus (seeded RANSAC),
geometric least squares, robust.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from ...errors import PanomapError
from ...geometry import FloatArray, pixel_polar
from ...robust import mad_sigma
from .thresholds import (
    CONSENSUS_SAMPLES,
    ELLIPSE_MIN_ECCENTRICITY,
    GAUSS_NEWTON_ITERATIONS,
    INLIER_SIGMAS,
    MIN_RIM_FRACTION,
    NEAR_FRACTION,
    NEAR_PX,
    RAYS,
    RIM_CORRELATED_RAYS,
)
from .types import Circle, Ellipse


def _algebraic_circle(points: FloatArray) -> tuple[tuple[float, float], float]:
    """Least-squares circle through points (n, 2) in the algebraic sense (Kasa), refitted on the closer half."""
    use = points
    for _ in range(2):
        x, y = use[:, 0], use[:, 1]
        design = np.stack([x, y, np.ones_like(x)], axis=-1)
        (a, b, c), *_ = np.linalg.lstsq(design, x**2 + y**2, rcond=None)
        cu, cv = a / 2, b / 2
        radius = math.sqrt(max(c + cu**2 + cv**2, 0.0))
        distance = np.abs(np.hypot(points[:, 0] - cu, points[:, 1] - cv) - radius)
        use = points[distance <= np.median(distance) * 2 + 1]
    return (float(cu), float(cv)), radius


def _robust_circle(points: FloatArray, centre: tuple[float, float], radius: float, consensus: bool = True) -> Circle:
    """Geometric circle fit: a consensus circle, then least squares on the points near it, three times.

    The points within NEAR_PX (or NEAR_FRACTION of the radius) of the consensus circle (of the start circle, without
    ``consensus``: it is already close) give the first fit and the spread; the
    inliers are then the points within INLIER_SIGMAS of it.
    """

    def residuals(p: FloatArray, xy: FloatArray) -> FloatArray:
        return np.hypot(xy[:, 0] - p[0], xy[:, 1] - p[1]) - p[2]

    if consensus:
        centre, radius = _consensus_circle(points, centre, radius)
    params = np.array([centre[0], centre[1], radius], dtype=np.float64)
    near = max(NEAR_PX, NEAR_FRACTION * radius)
    inliers = np.abs(residuals(params, points)) < near
    for _ in range(3):
        if inliers.sum() < 3:
            raise PanomapError("no circle found: too few consistent edge points")
        params = _least_squares_circle(points[inliers], params)
        r = residuals(params, points)
        sigma = max(mad_sigma(r[inliers], centre="median"), 0.1)
        inliers = np.abs(r) < min(INLIER_SIGMAS * sigma, near)
    if inliers.sum() < 3:
        raise PanomapError("no circle found: too few consistent edge points")
    r = residuals(params, points[inliers])
    return Circle(
        centre=(float(params[0]), float(params[1])),
        radius=float(params[2]),
        rms_px=float(np.sqrt(np.mean(r**2))),
        inliers=int(inliers.sum()),
        rays=RAYS,
    )


def _least_squares_circle(points: FloatArray, start: FloatArray) -> FloatArray:
    """Geometric least-squares circle ``[u, v, r]`` through points (n, 2), by Gauss-Newton from ``start``."""
    params = np.array(start, dtype=np.float64)
    for _ in range(GAUSS_NEWTON_ITERATIONS):
        du, dv = points[:, 0] - params[0], points[:, 1] - params[1]
        distance = np.hypot(du, dv)
        if np.any(distance == 0):
            raise PanomapError("the circle fit did not converge (an edge point at the centre)")
        cu, cv = du / distance, dv / distance
        residual = distance - params[2]
        # Normal equations of the Jacobian [-cu, -cv, -1] (3 x 3: cheap, and well conditioned for an arc).
        normal = np.array(
            [
                [np.dot(cu, cu), np.dot(cu, cv), cu.sum()],
                [np.dot(cu, cv), np.dot(cv, cv), cv.sum()],
                [cu.sum(), cv.sum(), float(len(cu))],
            ]
        )
        try:
            step = np.linalg.solve(normal, np.array([np.dot(cu, residual), np.dot(cv, residual), residual.sum()]))
        except np.linalg.LinAlgError:
            raise PanomapError("the circle fit did not converge (the edge points do not constrain a circle)") from None
        params += step
        if float(np.max(np.abs(step))) < 1e-7:
            return params
    raise PanomapError(f"the circle fit did not converge in {GAUSS_NEWTON_ITERATIONS} iterations")


def centre_uncertainty_px(points: FloatArray, circle: Circle) -> float:
    """The standard error (px) of a fitted circle's centre along its worst direction, from its inlier points (n, 2)
    [u, v] px: the least-squares covariance ``rms**2 * inv(J^T J)`` (J: each point's row ``[-cos, -sin, -1]``),
    its centre block's largest eigenvalue, times RIM_CORRELATED_RAYS (neighbouring rays' residuals are not
    independent: the rays lie 0.5 deg apart, a soft or irregular rim strays over many of them).

    A rim seen all round fixes its centre to a few hundredths of its RMS; one arc fixes it only across the arc:
    along the arc's bisector the centre trades with the radius (over 60 deg of arc, 6x worse than over 180).
    """
    du, dv = points[:, 0] - circle.centre[0], points[:, 1] - circle.centre[1]
    distance = np.hypot(du, dv)
    on = np.abs(distance - circle.radius) < max(INLIER_SIGMAS * circle.rms_px, 0.5)
    if on.sum() < 3:
        return math.inf
    jacobian = np.stack([-du[on] / distance[on], -dv[on] / distance[on], -np.ones(int(on.sum()))], axis=1)
    try:
        covariance = np.linalg.inv(jacobian.T @ jacobian) * max(circle.rms_px, 0.1) ** 2 * RIM_CORRELATED_RAYS
    except np.linalg.LinAlgError:
        return math.inf
    return float(math.sqrt(max(float(np.linalg.eigvalsh(covariance[:2, :2]).max()), 0.0)))


def _consensus_circle(
    points: FloatArray, centre: tuple[float, float], radius: float
) -> tuple[tuple[float, float], float]:
    """The circle through three of the points that most points lie within 1.5 px of (seeded RANSAC).

    Circles far from the start (centre moved by more than a third of the radius, or
    radius changed by more than a third) are not considered; the start circle itself
    is, so that a good start is kept.
    """
    rng = np.random.default_rng(0)
    triples = points[rng.integers(0, len(points), (CONSENSUS_SAMPLES, 3))]
    (ax, ay), (bx, by), (cx, cy) = (triples[:, k].T for k in range(3))
    d = 2 * (ax * (by - cy) + bx * (cy - ay) + cx * (ay - by))
    with np.errstate(divide="ignore", invalid="ignore"):
        a2, b2, c2 = ax**2 + ay**2, bx**2 + by**2, cx**2 + cy**2
        us = (a2 * (by - cy) + b2 * (cy - ay) + c2 * (ay - by)) / d
        vs = (a2 * (cx - bx) + b2 * (ax - cx) + c2 * (bx - ax)) / d
    rs = np.hypot(ax - us, ay - vs)
    plausible = (
        np.isfinite(us) & (np.hypot(us - centre[0], vs - centre[1]) < radius / 3) & (np.abs(rs - radius) < radius / 3)
    )
    us = np.concatenate([[centre[0]], us[plausible]])
    vs = np.concatenate([[centre[1]], vs[plausible]])
    rs = np.concatenate([[radius], rs[plausible]])
    distance = np.abs(np.hypot(points[None, :, 0] - us[:, None], points[None, :, 1] - vs[:, None]) - rs[:, None])
    best = int(np.argmax(np.sum(distance < 1.5, axis=1)))
    return (float(us[best]), float(vs[best])), float(rs[best])


def _ellipse(points: FloatArray, circle: Circle) -> Ellipse | None:
    """The rim as an ellipse, when it is measurably one (else None)."""
    distance = pixel_polar(points, circle.centre)[0] - circle.radius
    inliers = points[np.abs(distance) < max(INLIER_SIGMAS * circle.rms_px, 0.5)]
    if len(inliers) < MIN_RIM_FRACTION * RAYS:
        return None
    (cu, cv), (d1, d2), angle = cv2.fitEllipse(inliers.astype(np.float32))
    a, b = d1 / 2, d2 / 2
    if abs(a - b) / (a + b) < ELLIPSE_MIN_ECCENTRICITY:
        return None
    # Only when the ellipse explains the rim clearly better than the circle.
    residual = _ellipse_rms(inliers, (cu, cv), (a, b), angle)
    if residual > min(0.7 * circle.rms_px, 1.0):
        return None
    return Ellipse(centre=(float(cu), float(cv)), semi_axes=(float(a), float(b)), angle_deg=float(angle))


def _ellipse_rms(points: FloatArray, centre: tuple[float, float], axes: tuple[float, float], angle_deg: float) -> float:
    """Approximate RMS geometric distance of points from an ellipse (px)."""
    theta = math.radians(angle_deg)
    dx, dy = points[:, 0] - centre[0], points[:, 1] - centre[1]
    x = dx * math.cos(theta) + dy * math.sin(theta)
    y = -dx * math.sin(theta) + dy * math.cos(theta)
    a, b = axes
    level = np.sqrt((x / a) ** 2 + (y / b) ** 2)
    # Distance along the ray from the centre, first order.
    distance = (level - 1.0) * np.hypot(x, y) / np.maximum(level, 1e-12)
    return float(np.sqrt(np.mean(distance**2)))
