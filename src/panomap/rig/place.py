"""A surround rig placed from floor landmarks: each camera's pose in one world (the paper's own method, issue 52,
item 4 (c)).

Convention (docs/conventions.md, "A rig"): world Z up, the floor landmarks at Z = 0 (any unit, used for the
camera positions too); each camera's rotation ``R`` takes its axes to the world's and its centre is ``C``, so a
floor point ``P`` is seen along ``c ~ R^T (P - C)`` in the camera's axes. Pixels as everywhere: (u, v), the
top-left pixel's centre at (0, 0).

How (:func:`place_on_floor`): each landmark's pixel is unprojected through its camera's table (its lens, known)
into a unit ray in the camera's axes; the plane's homography ``H = [r1, r2, t]`` (``c ~ H (X, Y, 1)``,
``R^T = [r1, r2, r1 x r2]``, ``t = -R^T C``) is found linearly (``c x H p = 0``, the data normalised), made a
rotation, then refined by Gauss-Newton on the rays' angles (6 unknowns a camera, capped, with a step
tolerance). Rays beyond 90 deg from the axis are as good as any: no pinhole plane is involved.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike

from ..camera.orientation import rotation_from_vector
from ..errors import PanomapError
from ..geometry import FloatArray, ray_from_angles
from ..table.table import PanoMappingTable
from .learn import rotation_of, turned_table
from .rig import CameraRig

# Landmarks a camera needs at least (a homography's four; more to see the residuals).
MIN_LANDMARKS = 4
MAX_STEPS = 50
STEP_TOLERANCE = 1e-12
# Landmarks within this fraction of their spread of one line count as on it.
COLLINEAR_FRACTION = 1e-3
# Rays this far (deg, median) from their landmarks at the best pose: no pose explains them, refused.
MAX_MEDIAN_DEG = 2.0
CM_PER_UNIT = {"m": 100.0, "cm": 1.0, "mm": 0.1}


@dataclass(frozen=True)
class PlacedCamera:
    """One camera's pose from its floor landmarks: ``rotation`` (3, 3, camera to world), ``centre`` (3,),
    the landmarks used and how far the placed camera misses them: their rays' angle to the landmarks (deg),
    the landmarks projected through the placed table against their pixels (px), and the rays' floor points'
    distance from the landmarks (world units); each median, p90 and max."""

    name: str
    rotation: FloatArray
    centre: FloatArray
    landmarks: int
    residual_deg_median: float
    residual_deg_p90: float
    residual_px_median: float
    residual_px_p90: float
    residual_px_max: float
    floor_median: float
    floor_p90: float
    floor_max: float

    def describe(self, unit: str | None = None) -> str:
        """One line; ``unit`` (``m``, ``cm`` or ``mm``: the landmarks' world unit) gives the floor's figures in
        cm, None in world units."""
        x, y, z = self.centre
        scale, shown = (1.0, "world units") if unit is None else (CM_PER_UNIT[unit], "cm")
        floor = f"{self.floor_median * scale:.3g}, p90 {self.floor_p90 * scale:.3g}, max {self.floor_max * scale:.3g}"
        return (
            f"{self.name}: at ({x:.4g}, {y:.4g}, {z:.4g}) from {self.landmarks} landmarks; residual median "
            f"{self.residual_px_median:.2f} px, p90 {self.residual_px_p90:.2f}, max {self.residual_px_max:.2f} "
            f"({self.residual_deg_median:.3f} deg median); on the floor median {floor} {shown}"
        )


@dataclass(frozen=True)
class PlacedRig:
    """The rig with every camera placed, and each camera's :class:`PlacedCamera`."""

    rig: CameraRig
    cameras: tuple[PlacedCamera, ...]

    def describe(self, unit: str | None = None) -> list[str]:
        return [camera.describe(unit) for camera in self.cameras]


def camera_rays(table: PanoMappingTable, pixels: ArrayLike) -> FloatArray:
    """Unit rays (n, 3) in the camera's own axes of pixels (n, 2), through its table (NaN where it sees none)."""
    theta, rho = table.unproject(np.asarray(pixels, dtype=np.float64))
    return np.asarray(ray_from_angles(theta, rho) @ rotation_of(table))


def floor_pose(rays: FloatArray, points: FloatArray) -> tuple[FloatArray, FloatArray, int]:
    """(R (3, 3), C (3,), steps) of a camera whose unit rays ``rays`` (n, 3) in its axes see the floor points
    ``points`` (n, 2) (X, Y at Z = 0).

    Raises
    ------
    PanomapError
        If fewer than :data:`MIN_LANDMARKS`, the points lie on one line, or the refinement does not converge.
    """
    n = len(rays)
    if n < MIN_LANDMARKS:
        raise PanomapError(f"{n} floor landmarks: a camera needs {MIN_LANDMARKS} or more, not all on one line")
    mean = points.mean(axis=0)
    spread = float(np.sqrt(np.mean(np.sum((points - mean) ** 2, axis=1))))
    if spread == 0 or off_one_line(points, COLLINEAR_FRACTION * spread) < 2:
        raise PanomapError("the floor landmarks lie on one line (all but one at most): they fix no pose")
    q = np.column_stack([(points - mean) / spread, np.ones(n)])  # normalised floor points
    # c x (H q) = 0: two independent rows of three per point, linear in H's 9 entries (row-major).
    rows = []
    for c, p in zip(rays, q, strict=True):
        cross = np.array([[0, -c[2], c[1]], [c[2], 0, -c[0]], [-c[1], c[0], 0]])
        rows.append(np.kron(cross, p))
    h = np.linalg.svd(np.concatenate(rows))[2][-1].reshape(3, 3)
    if np.median(np.sum(rays * (q @ h.T), axis=1)) < 0:
        h = -h  # the points in front of the rays, not behind
    scale = (np.linalg.norm(h[:, 0]) + np.linalg.norm(h[:, 1])) / 2
    r1, r2, t = h[:, 0] / scale, h[:, 1] / scale, h[:, 2] / scale
    u, _, vt = np.linalg.svd(np.column_stack([r1, r2, np.cross(r1, r2)]))
    rt = u @ np.diag([1.0, 1.0, np.linalg.det(u @ vt)]) @ vt  # R^T, the closest rotation
    # Back to world units: P = spread q + mean, so t' = t spread - R^T (mean, 0) ... as the centre C.
    rotation = rt.T
    centre = -rotation @ t * spread + np.array([mean[0], mean[1], 0.0])
    world = np.column_stack([points, np.zeros(n)])
    for step in range(1, MAX_STEPS + 1):
        d = world - centre
        norm = np.linalg.norm(d, axis=1)
        seen = d / norm[:, None]
        predicted = rays @ rotation.T  # the rays in world axes
        r = (predicted - seen).ravel()
        # d(exp(w) R c)/dw = -[R c]x; d(seen)/dC = -(I - s s^T)/|d|.
        jac_w = -_skew(predicted)
        jac_c = (np.eye(3)[None] - seen[:, :, None] * seen[:, None, :]) / norm[:, None, None]
        jac = np.concatenate([jac_w, jac_c], axis=2).reshape(-1, 6)
        delta = -np.linalg.lstsq(jac, r, rcond=None)[0]
        rotation = rotation_from_vector(delta[:3]) @ rotation
        centre = centre + delta[3:]
        if np.max(np.abs(delta[:3])) < STEP_TOLERANCE and np.max(np.abs(delta[3:])) < STEP_TOLERANCE * max(1.0, spread):
            return rotation, centre, step
    raise PanomapError(f"the camera's pose did not converge in {MAX_STEPS} steps: are the landmarks its own?")


def off_one_line(points: FloatArray, tolerance: float) -> int:
    """How many of ``points`` (n, 2), n >= 3, lie off the line through most of them, of the lines through two of
    the first three (one of which holds every point but one where all but one lie on a line); ``tolerance``
    (world units): the distance that counts as on it. Fewer than 2 off: the points fix no homography."""
    fewest = len(points)
    for i, j in ((0, 1), (0, 2), (1, 2)):
        d = points[j] - points[i]
        length = float(np.hypot(*d))
        if length <= tolerance:
            continue
        normal = np.array([-d[1], d[0]]) / length
        fewest = min(fewest, int(np.sum(np.abs((points - points[i]) @ normal) > tolerance)))
    return fewest


def _skew(v: FloatArray) -> FloatArray:
    out = np.zeros((len(v), 3, 3))
    out[:, 0, 1], out[:, 0, 2], out[:, 1, 2] = -v[:, 2], v[:, 1], -v[:, 0]
    out[:, 1, 0], out[:, 2, 0], out[:, 2, 1] = v[:, 2], -v[:, 1], v[:, 0]
    return out


def place_on_floor(
    rig: CameraRig,
    landmarks: Sequence[tuple[ArrayLike, ArrayLike]],
    *,
    turn: Callable[[PanoMappingTable, FloatArray], PanoMappingTable] = turned_table,
) -> PlacedRig:
    """Every camera of ``rig`` placed from its floor landmarks, in one world.

    Parameters
    ----------
    rig : CameraRig
        Each camera's table (its lens; its pose is replaced).
    landmarks : sequence of (pixels (n, 2), floor points (n, 2) or (n, 3))
        One per camera, in the rig's order: each landmark's pixel in that camera's picture and its world
        point on the floor (X, Y; a Z given must be 0).
    turn : callable, optional
        ``turn(table, rotation)``: the table with a new rotation (default
        :func:`panomap.rig.learn.turned_table`).

    Returns
    -------
    PlacedRig
        The rig, each camera turned by ``turn`` and moved to its centre, and each camera's residuals.

    Raises
    ------
    PanomapError
        Naming the camera, where its landmarks are fewer than :data:`MIN_LANDMARKS`, off the floor, unseen by
        its lens, on one line (all but one at most), putting the camera below the floor (X, Y mirrored), or
        missing their best pose by more than :data:`MAX_MEDIAN_DEG` (median).
    """
    if len(landmarks) != rig.count:
        raise PanomapError(f"floor landmarks for {len(landmarks)} cameras: the rig has {rig.count}")
    # Every camera's pose first, so that a refusal comes before any table is turned.
    poses = [_camera_pose(name, table, pixels, points) for name, table, (pixels, points) in
             zip(rig.names, rig.tables, landmarks, strict=True)]  # fmt: skip
    tables, placed = [], []
    for name, table, (uv, floor, rays, rotation, centre) in zip(rig.names, rig.tables, poses, strict=True):
        moved = replace(turn(table, rotation), camera_position=(float(centre[0]), float(centre[1]), float(centre[2])))
        tables.append(moved)
        placed.append(_report(name, moved, uv, rays, floor))
    info = {**rig.info, "poses": "placed from floor landmarks"}
    return PlacedRig(replace(rig, tables=tuple(tables), info=info), tuple(placed))


def _camera_pose(
    name: str, table: PanoMappingTable, pixels: ArrayLike, points: ArrayLike
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """One camera's landmarks checked and its pose: pixels (n, 2), floor points (n, 2), rays (n, 3) in its axes,
    rotation (3, 3), centre (3,); refusals name the camera."""
    uv = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
    world = np.asarray(points, dtype=np.float64)
    if world.ndim != 2 or world.shape[1] not in (2, 3) or len(world) != len(uv):
        raise PanomapError(f"camera {name}: one floor point (X, Y) per landmark pixel")
    if world.shape[1] == 3 and np.any(world[:, 2] != 0):
        raise PanomapError(f"camera {name}: floor landmarks lie at Z = 0")
    floor = world[:, :2]
    rays = camera_rays(table, uv)
    seen = np.all(np.isfinite(rays), axis=1)
    if not seen.all():
        raise PanomapError(f"camera {name}: {int((~seen).sum())} landmark pixels are outside what its lens sees")
    try:
        rotation, centre, _ = floor_pose(rays, floor)
    except PanomapError as exc:
        raise PanomapError(f"camera {name}: {exc.detail}") from None
    if centre[2] <= 0:
        raise PanomapError(
            f"camera {name}: its landmarks put it below the floor (Z = {centre[2]:.3g}): are X, Y right-handed "
            "with Z up? (a mirrored floor turns the camera upside down)"
        )
    median_deg = float(np.median(_angles_deg(rays @ rotation.T, floor, centre)))
    if not median_deg <= MAX_MEDIAN_DEG:
        raise PanomapError(
            f"camera {name}: its landmarks miss their best pose by {median_deg:.1f} deg (median): wrong pixels, "
            "another camera's, or X, Y not right-handed with Z up?"
        )
    return uv, floor, rays, rotation, centre


def _angles_deg(world_rays: FloatArray, floor: FloatArray, centre: FloatArray) -> FloatArray:
    """The angles (deg) between rays (n, 3) in world axes from ``centre`` and the floor points (n, 2)."""
    d = np.column_stack([floor, np.zeros(len(floor))]) - centre
    cosine = np.sum(world_rays * d, axis=1) / np.linalg.norm(d, axis=1)
    return np.asarray(np.degrees(np.arccos(np.clip(cosine, -1.0, 1.0))))


def _report(
    name: str, table: PanoMappingTable, pixels: FloatArray, rays: FloatArray, floor: FloatArray
) -> PlacedCamera:
    """How far the placed camera (``table``) misses its landmarks: pixels (n, 2), their rays (n, 3) in its
    axes, their floor points (n, 2)."""
    rotation, centre = rotation_of(table), np.asarray(table.camera_position, dtype=np.float64)
    world = rays @ rotation.T
    points = np.column_stack([floor, np.zeros(len(floor))])
    angle = _angles_deg(world, floor, centre)
    with np.errstate(divide="ignore", invalid="ignore"):
        reach = -centre[2] / world[:, 2]
    hit = centre[None, :2] + reach[:, None] * world[:, :2]
    miss = np.where(reach > 0, np.linalg.norm(hit - floor, axis=1), np.inf)
    projected = np.asarray(table.project(points), dtype=np.float64)
    px = np.hypot(*(projected - pixels).T)
    px = np.where(np.isfinite(px), px, np.inf)  # a landmark the placed lens does not see: missed outright
    return PlacedCamera(
        name,
        rotation,
        centre,
        len(floor),
        float(np.median(angle)),
        float(np.percentile(angle, 90)),
        float(np.median(px)),
        float(np.percentile(px, 90)),
        float(np.max(px)),
        float(np.median(miss)),
        float(np.percentile(miss, 90)),
        float(np.max(miss)),
    )
