"""Level a table from its pictures' vertical lines: the camera's pitch and roll, its yaw kept (``panomap level``).

Convention: world rays as :mod:`panomap.geometry` (Z up); orientation as a perspective view's yaw, pitch and
roll (:mod:`panomap.camera.orientation`).

Method. The edge arcs of each picture (:func:`panomap.calibrate.lines.arcs.find_arcs`) are turned into world
rays through the table as it stands; an arc that is the image of a straight world line puts its rays on a plane
through the camera, whose unit normal ``n`` is the smallest singular vector of its rays (kept where its rays lie
within ``STRAIGHT_PX`` of the plane, as pixels, and span ``MIN_SPAN_DEG``). A vertical line's plane holds the
true vertical ``up``: ``n . up = 0``. Two such planes meet along ``up = n_i x n_j``; the pair whose ``up`` holds
the most arc length within ``INLIER_DEG`` (and lies within ``MAX_CHANGE_DEG`` of the table's vertical) starts,
and ``up`` is then the smallest eigenvector of ``sum w n n^T`` over the planes within the band (weighted by the
number of the arc's pixels), the band narrowed twice. The smallest rotation taking ``up`` to world Z turns the
camera; its yaw is then set back to the table's.

How sure: the residuals ``n . up`` of the inliers give their scatter ``sigma^2`` (the verticals of a real room
are not exactly vertical, and their normals carry the pixels' noise); the covariance of ``up``'s two tilt angles
is ``sigma^2 H^-1``, ``H`` the inliers' ``sum w n n^T`` across ``up`` (each arc's weight made one line's:
its pixels are not independent). The report gives the 95% bound of the axis' error, ``sqrt(5.99 * largest
eigenvalue)``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .. import inputs
from ..camera.orientation import orientation_of_rotation, rotation_from_vector
from ..errors import PanomapError
from ..geometry import FloatArray, ray_from_angles
from ..interop.orient import orient_table
from ..table.table import PanoMappingTable, check_table
from .circles.types import Circle, ImageCircles
from .lines.arcs import EdgeArc, find_arcs

#: The start must lie within this of the truth (deg): only planes whose normal is this close to horizontal
#: under the table's orientation are candidates, and the vertical found may turn no further.
MAX_CHANGE_DEG = 20.0
#: An arc is a straight line's where its rays lie this close (RMS, as pixels at the table's scale) to one plane.
STRAIGHT_PX = 1.0
#: ... and where its end rays lie at least this far apart (deg): a short arc's plane is loose.
MIN_SPAN_DEG = 4.0
#: A plane holds the vertical where ``n . up`` is within this (deg), in the search; then 1.5 and 0.75 x it.
INLIER_DEG = 1.0
#: Fewer vertical lines than this pin nothing.
MIN_VERTICALS = 4
#: Random pairs tried for the start.
PAIRS = 2000
#: chi-square's 95th percentile with 2 degrees of freedom.
CHI2_95_2 = 5.991


@dataclass(frozen=True)
class LevelResult:
    """The table levelled, and how.

    Attributes
    ----------
    table : PanoMappingTable
        The table turned so that the vertical lines are vertical (its yaw kept).
    orientation_deg : (yaw, pitch, roll)
        The levelled camera's orientation (deg).
    turned_deg : float
        How far the camera's vertical moved (deg).
    vertical_lines : int
        Arcs taken as vertical lines (inliers), of ``straight_lines`` straight arcs.
    straight_lines : int
    uncertainty_deg : float
        95% bound of the levelled axis' error (deg), from the inliers' scatter.
    """

    table: PanoMappingTable
    orientation_deg: tuple[float, float, float]
    turned_deg: float
    vertical_lines: int
    straight_lines: int
    uncertainty_deg: float

    def to_dict(self) -> dict[str, Any]:
        return {
            "yaw_deg": self.orientation_deg[0],
            "pitch_deg": self.orientation_deg[1],
            "roll_deg": self.orientation_deg[2],
            "turned_deg": self.turned_deg,
            "vertical_lines": self.vertical_lines,
            "straight_lines": self.straight_lines,
            "uncertainty_deg_95": self.uncertainty_deg,
            "source": "levelled from the pictures' vertical lines",
        }


def table_circles(table: PanoMappingTable) -> ImageCircles:
    """The table's annulus as the circles :func:`find_arcs` searches within."""
    centre = table.model.centre
    outer = Circle(centre, float(table.outer_radius), 0.0, 0, 0)
    cutoff = Circle(centre, float(table.cutoff_radius), 0.0, 0, 0) if table.cutoff_radius > 0 else None
    return ImageCircles(centre=centre, outer=outer, cutoff=cutoff, ellipse=None)


def arc_planes(table: PanoMappingTable, arcs: Sequence[EdgeArc]) -> tuple[FloatArray, FloatArray]:
    """Unit normals (k, 3) of the straight arcs' planes (world axes, as the table stands) and their weights (k,)."""
    px_per_rad = max(float(table.outer_radius - table.cutoff_radius), 1.0) / max(
        float(np.ptp(table.camera_range)), 1e-6
    )
    normals, weights = [], []
    for arc in arcs:
        theta, rho = table.unproject(arc.pixels)
        good = np.isfinite(theta) & np.isfinite(rho)
        if good.sum() < 8:
            continue
        rays = ray_from_angles(theta[good], rho[good])
        if math.degrees(math.acos(min(1.0, float(rays[0] @ rays[-1])))) < MIN_SPAN_DEG:
            continue
        _, singular, vt = np.linalg.svd(rays, full_matrices=False)
        if singular[2] / math.sqrt(len(rays)) * px_per_rad > STRAIGHT_PX:
            continue
        normals.append(vt[2])
        weights.append(float(len(rays)))
    if not normals:
        return np.zeros((0, 3)), np.zeros(0)
    return np.asarray(normals), np.asarray(weights)


def vertical_of_planes(
    normals: FloatArray, weights: FloatArray, start: FloatArray, seed: int = 0
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """The direction (3,) that the most planes hold (near ``start``), and which planes hold it."""
    limit = math.sin(math.radians(MAX_CHANGE_DEG + 5.0))
    candidates = np.flatnonzero(np.abs(normals @ start) < limit)
    if candidates.size < 2:
        raise PanomapError("no vertical lines")
    rng = np.random.default_rng(seed)
    band = math.sin(math.radians(INLIER_DEG))
    best, best_score = start, -1.0
    for _ in range(PAIRS):
        i, j = rng.choice(candidates, 2, replace=False)
        up = np.cross(normals[i], normals[j])
        size = float(np.linalg.norm(up))
        if size < math.sin(math.radians(10.0)):  # nearly the same plane: a loose vertical
            continue
        up = up / size * (1.0 if up @ start >= 0 else -1.0)
        if up @ start < math.cos(math.radians(MAX_CHANGE_DEG)):
            continue
        score = float(weights[np.abs(normals @ up) < band].sum())
        if score > best_score:
            best, best_score = up, score
    up = best
    for factor in (1.5, 1.0, 0.75):
        inliers = np.abs(normals @ up) < math.sin(math.radians(factor * INLIER_DEG))
        if inliers.sum() < 2:
            break
        scatter = (normals[inliers] * weights[inliers, None]).T @ normals[inliers]
        _, vectors = np.linalg.eigh(scatter)
        up = vectors[:, 0] * (1.0 if vectors[:, 0] @ start >= 0 else -1.0)
    return up, np.abs(normals @ up) < math.sin(math.radians(0.75 * INLIER_DEG))


def vertical_uncertainty_deg(normals: FloatArray, up: FloatArray) -> float:
    """95% bound (deg) of ``up``'s error from the inliers' normals (each one line)."""
    residuals = normals @ up
    count = len(normals)
    sigma2 = float(residuals @ residuals) / max(count - 2, 1)
    # Two directions across up.
    helper = np.array([1.0, 0.0, 0.0]) if abs(up[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(up, helper)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(up, e1)
    across = normals @ np.stack([e1, e2], axis=1)  # (k, 2): how each normal moves with a tilt of up
    hessian = across.T @ across
    if np.linalg.cond(hessian) > 1e8:
        return math.inf
    covariance = sigma2 * np.linalg.inv(hessian)
    return math.degrees(math.sqrt(CHI2_95_2 * float(np.linalg.eigvalsh(covariance)[-1])))


def level_table(
    table: PanoMappingTable, images: Sequence[NDArray[Any]], names: Sequence[str] | None = None
) -> LevelResult:
    """``table`` turned so that its pictures' vertical lines are vertical; its yaw kept.

    Parameters
    ----------
    table : PanoMappingTable
        The camera's table, its orientation within ``MAX_CHANGE_DEG`` (20 deg) of the truth.
    images : sequence of (H, W[, C]) arrays
        Pictures of the camera (the table's image size), their lines pooled.
    names : sequence of str, optional
        The pictures' names, for messages.

    Raises
    ------
    PanomapError
        Where the pictures show fewer than ``MIN_VERTICALS`` vertical lines, or ones that do not pin the vertical
        (all in one plane).
    """
    check_table(table)
    images = inputs.pictures(images, "pictures")
    if not images:
        raise PanomapError("no picture to level the camera from")
    if names is not None and (isinstance(names, str | bytes) or len(names) != len(images)):
        raise PanomapError(f"give one name per picture ({len(images)}), not {names!r:.40}")
    for k, image in enumerate(images):
        if table.image_size is not None and (image.shape[1], image.shape[0]) != tuple(table.image_size):
            width, height = table.image_size
            name = names[k] if names is not None else f"picture {k + 1}"
            raise PanomapError(
                f"{name} is {image.shape[1]} x {image.shape[0]}, the table is for {width} x {height} images"
            )
    names = list(names) if names is not None else [f"picture {k + 1}" for k in range(len(images))]
    circles = table_circles(table)
    arcs: list[EdgeArc] = []
    for k, image in enumerate(images):
        arcs += find_arcs(image, circles, image_index=k)
    normals, weights = arc_planes(table, arcs)
    start = np.array([0.0, 0.0, 1.0])
    what = names[0] if len(names) == 1 else f"the {len(names)} pictures"
    try:
        up, inliers = vertical_of_planes(normals, weights, start)
    except PanomapError:
        inliers = np.zeros(len(normals), dtype=bool)
        up = start
    if inliers.sum() < MIN_VERTICALS:
        raise PanomapError(
            f"{what}: {int(inliers.sum())} vertical lines found (of {len(normals)} straight edges); levelling needs "
            f"{MIN_VERTICALS} or more within {MAX_CHANGE_DEG:g} deg of the table's vertical (door and window frames, "
            "wall corners, poles)"
        )
    uncertainty = vertical_uncertainty_deg(normals[inliers], up)
    if not math.isfinite(uncertainty):
        raise PanomapError(f"{what}: the vertical lines all lie in one plane, which does not pin the vertical")
    turn = np.cross(up, [0.0, 0.0, 1.0])
    sine, cosine = float(np.linalg.norm(turn)), float(up[2])
    correction = rotation_from_vector(turn / sine * math.atan2(sine, cosine)) if sine > 1e-15 else np.eye(3)
    model = table.model
    rotation = correction @ (np.eye(3) if model.rotation is None else np.asarray(model.rotation))
    yaw_old, _, _ = model.orientation
    # (Looking straight up or down after the turn, yaw and roll turn alike: the yaw kept, the roll is 0.)
    _, pitch, roll = orientation_of_rotation(rotation, model.axis, model.s, model.phi0)
    levelled = orient_table(table, yaw_old, pitch, roll)
    result = LevelResult(
        table=levelled,
        orientation_deg=(math.degrees(yaw_old), math.degrees(pitch), math.degrees(roll)),
        turned_deg=math.degrees(math.atan2(sine, cosine)),
        vertical_lines=int(inliers.sum()),
        straight_lines=len(normals),
        uncertainty_deg=uncertainty,
    )
    return replace(result, table=replace(levelled, info=dict(levelled.info) | {"orientation": result.to_dict()}))
