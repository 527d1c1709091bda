"""A rig's rotations learned from its pictures: the turns between cameras whose lenses are known.

Convention (docs/conventions.md, "A rig"): each camera's rotation ``R_k`` takes its own axes to the world's
(``table.model.rotation``; None is the identity), so a world ray ``d`` is ``c = R_k^T d`` in camera k's axes.
Rays are unit (3,) vectors; angles in rad inside, deg in the report; pixels as everywhere, (u, v) with the
top-left pixel's centre at (0, 0).

How (:func:`learn_rotations`):

1. **Each pair's overlap as a band** (:func:`band_of`): the directions equally far from both optical axes
   form the great circle about ``p = a_i - a_j``; the band is an equirectangular strip about it (longitude all
   round, latitude within the overlap's half-width plus a margin for the start's error), sampled from each
   camera through its table: a low-distortion layer of each camera, at the cameras' finest scale (px/rad).
2. **Features**: SIFT in each layer (within what it sees), matched by Lowe's ratio test and both ways.
   Each match is a pair of unit rays, each in its camera's axes (the band's ray under the start's pose,
   turned back by the start's rotation).
3. **RANSAC on the rotation** between each pair (two matches a sample, seeded), the cameras chained from
   camera 0 (which stays where it is: it places the world).
4. **Least squares** on all pairs' inliers together (Gauss-Newton on each camera's rotation vector; the
   residual is the chord between the two rays, the angle to 1e-7 at these sizes), with Cauchy weights, so
   that far points (no parallax) weigh most. Then once more from the refined poses, with a narrow margin.

5. **Parallax** (a rig of two cameras, :mod:`panomap.rig.parallax`): the lenses' centres a little apart, near
   objects' parallax moves their matches across the overlap's ring, which least squares reads as a tilt; the tilt
   is bounded by the far matches' side of it, and the report says how far it is pinned (``LearnedRig.parallax``).

Matches whose residual stays beyond three robust sigmas but within :data:`NEAR_PX` are counted as near
objects (their parallax between the two lens centres, or a match the rotation cannot explain), not inliers.
The report gives, per pair, matches, inliers, near matches, the residual (deg and px, in the cameras'
pictures through their tables), and per camera the rotation's 1-sigma uncertainty (deg) from the normal
equations. Too few matches refuse in one line.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from ..camera.orientation import rotation_from_vector, world_elevation_range
from ..errors import PanomapError
from ..geometry import FloatArray, azimuth_elevation, ray_from_angles
from ..robust import mad_sigma
from ..table.table import PanoMappingTable, fill_entries
from .parallax import ParallaxFit, baseline_of, settle
from .rig import CameraRig

# Inliers of a pair below which it is refused.
MIN_INLIERS = 12
# Lowe's ratio test.
RATIO = 0.8
# RANSAC: samples, and the inlier threshold (px at the band's scale).
RANSAC_SAMPLES = 2000
RANSAC_PX = 3.0
# Matches within this (px) of the learned rotation, but beyond three robust sigmas, are near objects.
NEAR_PX = 12.0
# The band's margin beyond the overlap (deg) at the start, and on the second pass.
START_MARGIN_DEG = 4.0
REFINE_MARGIN_DEG = 1.0
# The band's half-width at most (deg), and its width at most (px).
MAX_BAND_DEG = 45.0
MAX_BAND_WIDTH = 8192
# Pixels of a layer this close (px) to the edge of what its camera sees hold no features.
EDGE_PX = 6
# Gauss-Newton: steps at most, and the step (rad) below which it has converged.
MAX_STEPS = 50
STEP_TOLERANCE_RAD = 1e-10
# After this many steps the robust weights are kept as they are: where matches sit at the weights' cut-off they
# flip in and out step after step, and the rotation wandered by about 5e-5 rad (0.003 deg) without settling (a
# lens 1% long against its rendered frame: "did not converge"); with the weights fixed the steps shrink to the
# tolerance in a few more.
FREEZE_WEIGHTS_STEP = 20


@dataclass(frozen=True)
class Matches:
    """One pair's matched features: rays (n, 3) in each camera's own axes, and pixels (n, 2) in its picture."""

    i: int
    j: int
    rays_i: FloatArray
    rays_j: FloatArray
    pixels_i: FloatArray
    pixels_j: FloatArray
    scale_px_per_rad: float

    @property
    def count(self) -> int:
        return int(self.rays_i.shape[0])


@dataclass(frozen=True)
class PairReport:
    """What one pair of cameras shared in its overlap, after learning.

    ``matches``: ratio-test matches in the band; ``inliers``: those the rotation explains (far points);
    ``near``: beyond three robust sigmas but within :data:`NEAR_PX` (near objects' parallax); residuals of the
    inliers in deg and in px (each ray through the other camera's table, against its feature; the two ways'
    mean); ``near_parallax_deg``: the near matches' median residual (None without any); ``along_px_p90`` /
    ``across_px_p90``: the inliers' residual's p90 along the ring of directions equally far from both axes and
    across it (px at the band's scale; the lenses' centres lie apart along their axes, so near objects' parallax
    lies across the ring, and along it the residual is the cameras' own).
    """

    cameras: tuple[str, str]
    matches: int
    inliers: int
    near: int
    residual_deg_median: float
    residual_deg_p90: float
    residual_px_median: float
    residual_px_p90: float
    near_parallax_deg: float | None
    along_px_p90: float = math.nan
    across_px_p90: float = math.nan

    def describe(self) -> str:
        near = f", {self.near} near (parallax median {self.near_parallax_deg:.2f} deg)" if self.near else ", none near"
        return (
            f"{self.cameras[0]} and {self.cameras[1]}: {self.matches} matches, {self.inliers} inliers{near}; residual "
            f"median {self.residual_deg_median:.3f} deg ({self.residual_px_median:.2f} px), p90 "
            f"{self.residual_deg_p90:.3f} deg ({self.residual_px_p90:.2f} px); p90 along the overlap's ring "
            f"{self.along_px_p90:.2f} px, across it {self.across_px_p90:.2f} px (where parallax lies)"
        )


@dataclass(frozen=True)
class OverlapFit:
    """What the overlap's tiles said (:func:`panomap.rig.overlap.learn_with_overlap`), px at the band's scale.

    ``camera``: the camera whose centre may move (camera 1); ``tiles``: textured tiles; ``p90_start_px`` /
    ``p90_px``: their shifts' p90 (length) at the features' rotation and at the end; ``held_roll_p90_px`` /
    ``held_centre_p90_px``: the left-out sectors' tiles' along-ring residual p90 predicted by a roll alone and by
    a roll and the centre's move (:func:`panomap.rig.overlap.sector_residuals`); ``centre_px`` (2,): the centre's
    move fitted; ``kept``: whether it was kept (the rig's table of ``camera`` carries it, and the rotation was
    learned anew with it); ``left_px``: the move the tiles ask for after it (its length; NaN where not kept):
    how well one step settled it (the tiles' model is linear to 0.15 px over 2 px moves on the Theta's overlap)."""

    camera: str
    tiles: int
    p90_start_px: float
    p90_px: float
    held_roll_p90_px: float
    held_centre_p90_px: float
    centre_px: tuple[float, float]
    kept: bool
    left_px: float

    def describe(self) -> str:
        move = f"{self.camera}'s centre moved ({self.centre_px[0]:+.2f}, {self.centre_px[1]:+.2f}) px"
        if self.kept:
            said = f"{move}: kept, the rig's table carries it (then {self.left_px:.2f} px more asked)"
        else:
            said = f"{move} fitted there: not kept, it does not predict left-out sectors clearly better"
        return (
            f"the overlap's {self.tiles} tiles: shifts p90 {self.p90_start_px:.2f} -> {self.p90_px:.2f} px; along the "
            f"ring, left-out sectors p90 {self.held_roll_p90_px:.2f} px by a roll alone, {self.held_centre_p90_px:.2f}"
            f" px with the centre; {said}"
        )


@dataclass(frozen=True)
class LearnedRig:
    """A rig whose rotations were learned from its pictures, and the report.

    ``rotations``: each camera's rotation (3, 3), camera to world; ``turned_deg``: how far each turned from
    the start; ``uncertainty_deg``: each rotation's 1-sigma uncertainty about its worst axis (camera 0: 0, it
    places the world); ``pairs``: each overlapping pair's :class:`PairReport`; ``steps``: Gauss-Newton steps of
    the last pass; ``overlap``: what the overlap's tiles said (:func:`panomap.rig.overlap.learn_with_overlap`), None
    where they were not asked.
    """

    rig: CameraRig
    rotations: tuple[FloatArray, ...]
    turned_deg: tuple[float, ...]
    uncertainty_deg: tuple[float, ...]
    pairs: tuple[PairReport, ...]
    steps: int
    overlap: OverlapFit | None = None
    parallax: ParallaxFit | None = None

    def describe(self) -> list[str]:
        lines = [
            f"{name}: turned {turned:.3f} deg from the start, "
            + (f"uncertainty {sigma:.4f} deg (1 sigma)" if math.isfinite(sigma) else "its tilt not bounded (below)")
            for name, turned, sigma in zip(self.rig.names, self.turned_deg, self.uncertainty_deg, strict=True)
        ]
        lines += [pair.describe() for pair in self.pairs]
        lines += list(self.parallax.describe()) if self.parallax is not None else []
        return lines + ([self.overlap.describe()] if self.overlap is not None else [])


def rotation_of(table: PanoMappingTable) -> FloatArray:
    """The camera's rotation (3, 3), camera to world (the identity for a level camera)."""
    rotation = table.model.rotation
    return np.eye(3) if rotation is None else np.asarray(rotation, dtype=np.float64)


def turned_table(table: PanoMappingTable, rotation: FloatArray) -> PanoMappingTable:
    """``table``'s camera with the rotation ``rotation`` (3, 3; camera to world), its entries made anew.

    A fitted table's entries are filled from its model (Algorithm 2); an imported table's are read from its
    own entries, each new world ray turned into the old table's world (``R_old R_new^T d``), bilinearly: within
    the table's own interpolation error (0.01 px over an ideal 960 px fisheye's table of one entry per pixel).
    ``panomap rig learn`` turns an imported table through its calibration instead (exact).
    """
    rows = tuple((float(row[0]), float(row[1]), float(row[2])) for row in rotation)
    model = replace(table.model, rotation=rows)
    camera_range = table.camera_range
    turned = model.rotation is not None
    elevation_range = world_elevation_range(camera_range, model.rotation, model.axis) if turned else camera_range
    if table.entries_from_model:
        entries = fill_entries(model, table.size, elevation_range, camera_range=camera_range if turned else None)
    else:
        m, n = table.size
        theta = 2 * math.pi * np.arange(m) / m
        rho = elevation_range[0] + np.arange(n) * (elevation_range[1] - elevation_range[0]) / n
        rays = ray_from_angles(*np.broadcast_arrays(theta[:, None], rho[None, :]))
        old = rays @ np.asarray(rotation, dtype=np.float64) @ rotation_of(table).T  # R_old R_new^T d, in rows
        entries = table.sample(*azimuth_elevation(old))
    return replace(
        table,
        entries=entries,
        elevation_range=elevation_range,
        model=model,
        camera_elevation_range=camera_range if turned else None,
    )


def learn_rotations(
    rig: CameraRig,
    pictures: Any,
    *,
    turn: Callable[[PanoMappingTable, FloatArray], PanoMappingTable] = turned_table,
    seed: int = 0,
) -> LearnedRig:
    """The rig's rotations learned from the features its cameras share in one or a few pictures.

    Parameters
    ----------
    rig : CameraRig
        Each camera's table, placed roughly (within a few degrees: the band's margin is
        :data:`START_MARGIN_DEG`); camera 0 stays where it is.
    pictures : array or sequence
        One shot as :class:`~panomap.rig.RigRemapper` takes it (one frame holding every camera's picture, or
        one picture per camera), or a list of such shots (frames; or lists of one picture per camera).
    turn : callable, optional
        ``turn(table, rotation)``: the table with a new rotation (default :func:`turned_table`).
    seed : int
        RANSAC's seed.

    Returns
    -------
    LearnedRig

    Raises
    ------
    PanomapError
        If no two cameras overlap, or a pair's features match too little to place it (fewer than
        :data:`MIN_INLIERS` inliers), naming the pair.
    """
    shots = _shots(rig, pictures)
    rng = np.random.default_rng(seed)
    start = [rotation_of(table) for table in rig.tables]
    current, rotations, steps = rig, start, 0
    matches: list[Matches] = []
    for margin_deg in (START_MARGIN_DEG, REFINE_MARGIN_DEG):
        matches = _all_matches(current, shots, margin_deg)
        # Each match's rays are in its cameras' axes: the chain and the refinement are of absolute rotations.
        rotations, steps = _refine(rig.count, matches, _chain(current, matches, rng))
        current = _with_rotations(rig, rotations, turn)
    parallax = None
    if rig.count == 2:
        least_squares = rotations[1]
        rotations[1], parallax = _settle_parallax(current, matches[0], rotations)
        parallax = replace(parallax, moved_deg=_angle_deg(rotations[1] @ least_squares.T))
        current = _with_rotations(rig, rotations, turn)
    # The report: the last pass's matches (found about the refined poses) against the learned rotations.
    uncertainty = _uncertainty(rig.count, matches, rotations)
    if parallax is not None:
        # Half the bound (about 3 sigmas of the roll, and the tilt's feasible set); inf where the tilt is not bounded.
        uncertainty = (0.0, max(uncertainty[1], parallax.bound_deg / 2))
    pairs = tuple(_pair_report(current, m, rotations) for m in matches)
    turned = tuple(_angle_deg(r @ s.T) for r, s in zip(rotations, start, strict=True))
    return LearnedRig(current, tuple(rotations), turned, uncertainty, pairs, steps, parallax=parallax)


def _settle_parallax(rig: CameraRig, m: Matches, rotations: list[FloatArray]) -> tuple[FloatArray, ParallaxFit]:
    """Camera j's rotation with its tilt bounded by the far matches and its roll from the parallax-free components
    (:mod:`panomap.rig.parallax`), and what that says."""
    axes = rig.optical_axes()
    centres = [np.asarray(table.camera_position, np.float64) for table in rig.tables]
    baseline, assumed = baseline_of(axes[m.i], axes[m.j], centres[m.i], centres[m.j])
    found = settle(
        m.rays_i @ rotations[m.i].T,
        m.rays_j,
        rotations[m.j],
        baseline,
        m.scale_px_per_rad,
        NEAR_PX / m.scale_px_per_rad,
    )
    fit = ParallaxFit(
        (rig.names[m.i], rig.names[m.j]),
        len(found.parallax_rad),
        found.far,
        found.sigma_rad * m.scale_px_per_rad,
        float(np.percentile(found.parallax_rad, 90)) * m.scale_px_per_rad if found.parallax_rad.size else math.nan,
        math.degrees(found.tilt_bound_rad),
        math.degrees(found.roll_sigma_rad),
        0.0,
        found.pinned,
        assumed,
        found.unbounded,
        found.why,
    )
    return found.rotation, fit


def _with_rotations(
    rig: CameraRig, rotations: list[FloatArray], turn: Callable[[PanoMappingTable, FloatArray], PanoMappingTable]
) -> CameraRig:
    tables = tuple(
        table if np.allclose(rotation, rotation_of(table), atol=1e-14) else turn(table, rotation)
        for table, rotation in zip(rig.tables, rotations, strict=True)
    )
    return replace(rig, tables=tables, info={**rig.info, "rotations": "learned from pictures (panomap rig learn)"})


def _angle_deg(rotation: FloatArray) -> float:
    return math.degrees(math.acos(float(np.clip((np.trace(rotation) - 1) / 2, -1.0, 1.0))))


def _shots(rig: CameraRig, pictures: Any) -> list[list[NDArray[np.float32]]]:
    """Each shot's grey picture (float32) per camera (a frame cut at each camera's offset)."""
    if rig.offsets is not None:
        frames = [pictures] if isinstance(pictures, np.ndarray) else list(pictures)
        shots = []
        for frame in frames:
            frame = np.asarray(frame)
            width, height = rig.frame_size or (0, 0)
            if frame.shape[:2] != (height, width):
                raise PanomapError(
                    f"a frame of {frame.shape[1]} x {frame.shape[0]} px: the rig's is {width} x {height}"
                )
            shot = []
            for (x, y), table in zip(rig.offsets, rig.tables, strict=True):
                w, h = table.image_size  # type: ignore[misc]
                shot.append(_grey(frame[y : y + h, x : x + w]))
            shots.append(shot)
        return shots
    items = list(pictures)
    groups = [items] if items and isinstance(items[0], np.ndarray) else [list(group) for group in items]
    shots = []
    for group in groups:
        if len(group) != rig.count:
            raise PanomapError(f"{len(group)} pictures in a shot of a rig of {rig.count} cameras: give one each")
        shot = []
        for picture, table, name in zip(group, rig.tables, rig.names, strict=True):
            picture = np.asarray(picture)
            if picture.shape[1::-1] != tuple(table.image_size):  # type: ignore[arg-type]
                raise PanomapError(
                    f"camera {name}'s picture is {picture.shape[1]} x {picture.shape[0]} px, not its size"
                )
            shot.append(_grey(picture))
        shots.append(shot)
    if not shots:
        raise PanomapError("no pictures to learn from")
    return shots


def _grey(picture: NDArray[Any]) -> NDArray[np.float32]:
    image = picture.astype(np.float32)
    if image.ndim == 3:
        image = image[..., :3].mean(axis=2) if image.shape[2] >= 3 else image[..., 0]
    if picture.dtype == np.uint16:
        image /= 257.0
    return image


@dataclass(frozen=True)
class Band:
    """An equirectangular strip about the great circle of directions equally far from two optical axes.

    Its pixel (x, y) (column, row; centres at integers) sees longitude ``2 pi (x + 0.5) / width`` about
    ``pole`` from ``e1`` toward ``e2`` and latitude ``half - 2 half (y + 0.5) / height`` (rad) toward ``pole``.
    """

    pole: FloatArray
    e1: FloatArray
    e2: FloatArray
    half_rad: float
    width: int
    height: int

    @property
    def scale_px_per_rad(self) -> float:
        return self.width / (2 * math.pi)

    def rays_at(self, xy: FloatArray) -> FloatArray:
        """Unit world rays (n, 3) at fractional pixels ``xy`` (n, 2)."""
        lon = 2 * math.pi * (xy[:, 0] + 0.5) / self.width
        lat = self.half_rad - 2 * self.half_rad * (xy[:, 1] + 0.5) / self.height
        around = np.cos(lon)[:, None] * self.e1 + np.sin(lon)[:, None] * self.e2
        return np.cos(lat)[:, None] * around + np.sin(lat)[:, None] * self.pole

    def rays(self) -> FloatArray:
        """Every pixel's ray (H, W, 3)."""
        y, x = np.mgrid[0 : self.height, 0 : self.width].astype(np.float64)
        xy = np.stack([x.ravel(), y.ravel()], axis=1)
        return self.rays_at(xy).reshape(self.height, self.width, 3)


def band_of(rig: CameraRig, i: int, j: int, margin_deg: float) -> Band | None:
    """The band about the overlap of cameras i and j, at the two cameras' finest scale there (px/rad) and
    ``margin_deg`` wider than the overlap each way; None where they do not overlap, even with the margin."""
    axes = rig.optical_axes()
    fields = np.radians(rig.half_fields_deg())
    between = math.acos(float(np.clip(axes[i] @ axes[j], -1, 1)))
    overlap = fields[i] + fields[j] - between
    margin = math.radians(margin_deg)
    if overlap + 2 * margin <= 0 or between < 1e-6:
        return None
    pole = axes[i] - axes[j]
    pole /= np.linalg.norm(pole)
    e1 = np.cross(pole, [0.0, 0.0, 1.0] if abs(pole[2]) < 0.9 else [1.0, 0.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(pole, e1)
    half = min(overlap / 2 + margin, math.radians(MAX_BAND_DEG))
    scale = max(_scale(rig.tables[k], pole, e1, e2) for k in (i, j))
    width = min(MAX_BAND_WIDTH, max(64, math.ceil(2 * math.pi * scale)))
    height = max(8, math.ceil(2 * half * width / (2 * math.pi)))
    return Band(pole, e1, e2, half, width, height)


def _scale(table: PanoMappingTable, pole: FloatArray, e1: FloatArray, e2: FloatArray) -> float:
    """The camera's finest scale (px/rad) along and across the band's circle, where it sees it (0: nowhere)."""
    lon = np.linspace(0, 2 * math.pi, 72, endpoint=False)
    rays = np.cos(lon)[:, None] * e1 + np.sin(lon)[:, None] * e2
    tangent = -np.sin(lon)[:, None] * e1 + np.cos(lon)[:, None] * e2
    h = 1e-3
    here = table.sample(*azimuth_elevation(rays)).astype(np.float64)
    steps = [
        np.linalg.norm(table.sample(*azimuth_elevation(rays + h * way)) - here, axis=1) / h for way in (tangent, pole)
    ]
    found = np.concatenate(steps)
    found = found[np.isfinite(found)]
    return float(np.max(found)) if found.size else 0.0


def _all_matches(rig: CameraRig, shots: list[list[NDArray[np.float32]]], margin_deg: float) -> list[Matches]:
    found = []
    for i in range(rig.count):
        for j in range(i + 1, rig.count):
            band = band_of(rig, i, j, margin_deg)
            if band is not None:
                found.append(_match_pair(rig, i, j, band, shots))
    if not found:
        raise PanomapError("no two of the rig's cameras overlap: there is nothing to learn their rotations from")
    return found


def _layer(table: PanoMappingTable, rays: FloatArray, picture: NDArray[np.float32]) -> tuple[Any, Any, Any]:
    """The camera's map (H, W, 2) of the band's rays, its layer (uint8) and where features may lie."""
    theta, rho = azimuth_elevation(rays)
    map_uv = table.sample(theta.astype(np.float32), rho.astype(np.float32))
    seen = np.all(np.isfinite(map_uv), axis=-1)
    map_u = np.where(seen, map_uv[..., 0], -1e4).astype(np.float32)
    map_v = np.where(seen, map_uv[..., 1], -1e4).astype(np.float32)
    layer = cv2.remap(picture, map_u, map_v, cv2.INTER_LINEAR)
    mask = cv2.erode(seen.astype(np.uint8), np.ones((2 * EDGE_PX + 1, 2 * EDGE_PX + 1), np.uint8))
    return map_uv, np.clip(np.rint(layer), 0, 255).astype(np.uint8), mask


def _match_pair(rig: CameraRig, i: int, j: int, band: Band, shots: list[list[NDArray[np.float32]]]) -> Matches:
    """SIFT in both cameras' layers of the band, matched by the ratio test and both ways, in every shot."""
    rays = band.rays()
    sift = cv2.SIFT_create(contrastThreshold=0.02)  # type: ignore[attr-defined]
    matcher = cv2.BFMatcher(cv2.NORM_L2)
    parts: list[tuple[FloatArray, FloatArray, FloatArray, FloatArray]] = []
    for shot in shots:
        found = []
        for k in (i, j):
            map_uv, layer, mask = _layer(rig.tables[k], rays, shot[k])
            keypoints, descriptors = sift.detectAndCompute(layer, mask)
            found.append((map_uv, keypoints, descriptors))
        (map_i, kp_i, des_i), (map_j, kp_j, des_j) = found
        if des_i is None or des_j is None or len(kp_i) < 2 or len(kp_j) < 2:
            continue
        back = {m[0].queryIdx: m[0].trainIdx for m in matcher.knnMatch(des_j, des_i, k=1) if m}
        pairs = [
            (m[0].queryIdx, m[0].trainIdx)
            for m in matcher.knnMatch(des_i, des_j, k=2)
            if len(m) == 2 and m[0].distance < RATIO * m[1].distance and back.get(m[0].trainIdx) == m[0].queryIdx
        ]
        if not pairs:
            continue
        xy_i = np.array([kp_i[a].pt for a, _ in pairs], dtype=np.float64)
        xy_j = np.array([kp_j[b].pt for _, b in pairs], dtype=np.float64)
        # Each feature's ray in its camera's axes: the band's world ray under the start's pose, R^T d.
        ray_i = band.rays_at(xy_i) @ rotation_of(rig.tables[i])
        ray_j = band.rays_at(xy_j) @ rotation_of(rig.tables[j])
        parts.append((ray_i, ray_j, _bilinear(map_i, xy_i), _bilinear(map_j, xy_j)))
    if not parts:
        empty3, empty2 = np.zeros((0, 3)), np.zeros((0, 2))
        return Matches(i, j, empty3, empty3, empty2, empty2, band.scale_px_per_rad)
    ri, rj, pi, pj = (np.concatenate(column) for column in zip(*parts, strict=True))
    return Matches(i, j, ri, rj, pi, pj, band.scale_px_per_rad)


def _bilinear(map_uv: NDArray[np.float32], xy: FloatArray) -> FloatArray:
    """The map's (u, v) (n, 2) at fractional pixels ``xy`` (n, 2)."""
    x, y = (xy[:, k].astype(np.float32)[None] for k in (0, 1))
    return cv2.remap(map_uv, x, y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)[0].astype(np.float64)


def _kabsch(a: FloatArray, b: FloatArray, weights: FloatArray | None = None) -> FloatArray:
    """The rotation Q (3, 3) that best takes rays ``b`` (n, 3) onto ``a`` (n, 3): ``a ~ Q b``."""
    w = np.ones(len(a)) if weights is None else weights
    u, _, vt = np.linalg.svd((a * w[:, None]).T @ b)
    d = np.sign(np.linalg.det(u @ vt))
    return np.asarray(u @ np.diag([1.0, 1.0, d]) @ vt)


def _ransac(a: FloatArray, b: FloatArray, threshold: float, rng: np.random.Generator) -> NDArray[np.bool_]:
    """Inliers of the rotation ``a ~ Q b`` found by RANSAC, two matches a sample, then refit on its inliers."""
    n = len(a)
    best = np.zeros(n, dtype=bool)
    if n < 2:
        return best
    for _ in range(RANSAC_SAMPLES):
        pick = rng.choice(n, 2, replace=False)
        if np.linalg.norm(np.cross(a[pick[0]], a[pick[1]])) < 1e-3:
            continue  # two rays along one line fix no rotation
        inliers = np.linalg.norm(a - b @ _kabsch(a[pick], b[pick]).T, axis=1) < threshold
        if inliers.sum() > best.sum():
            best = inliers
    if best.sum() >= 3:
        best = np.linalg.norm(a - b @ _kabsch(a[best], b[best]).T, axis=1) < threshold
    return best


def _chain(rig: CameraRig, matches: list[Matches], rng: np.random.Generator) -> list[FloatArray]:
    """Each camera's rotation from the pairs' RANSAC, chained from camera 0 (kept) through the pairs with the
    most inliers: ``R_i c_i = R_j c_j`` with ``c_i ~ Q c_j`` gives ``R_j = R_i Q``.

    Raises PanomapError naming the pair where a camera cannot be placed."""
    rotations: list[FloatArray | None] = [rotation_of(rig.tables[0])] + [None] * (rig.count - 1)
    ranked = []
    for m in matches:
        inliers = _ransac(m.rays_i, m.rays_j, RANSAC_PX / m.scale_px_per_rad, rng)
        ranked.append((int(inliers.sum()), m, inliers))
    ranked.sort(key=lambda item: -item[0])
    changed = True
    while changed:
        changed = False
        for count, m, inliers in ranked:
            r_i, r_j = rotations[m.i], rotations[m.j]
            if (r_i is None) == (r_j is None) or count < MIN_INLIERS:
                continue
            q = _kabsch(m.rays_i[inliers], m.rays_j[inliers])
            if r_i is not None:
                rotations[m.j] = r_i @ q
            elif r_j is not None:
                rotations[m.i] = r_j @ q.T
            changed = True
    for k, rotation in enumerate(rotations):
        if rotation is None:
            count, m, _ = max((item for item in ranked if k in (item[1].i, item[1].j)), key=lambda item: item[0])
            raise PanomapError(
                f"too few features match between {rig.names[m.i]} and {rig.names[m.j]} to place {rig.names[k]}: "
                f"{count} of {m.count} matches agree on one rotation, {MIN_INLIERS} needed"
            )
    return [r for r in rotations if r is not None]


def _jacobians(m: Matches, rotations: list[FloatArray]) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The residuals ``r = R_i c_i - R_j c_j`` (n, 3) and their Jacobians (n, 3, 3) in each camera's rotation
    vector (``R -> exp(w) R``): ``-[R_i c_i]x`` and ``+[R_j c_j]x``."""
    a, b = m.rays_i @ rotations[m.i].T, m.rays_j @ rotations[m.j].T
    return a - b, -_skew_rows(a), _skew_rows(b)


def _normal_equations(
    count: int, matches: list[Matches], rotations: list[FloatArray], weights: list[FloatArray]
) -> tuple[FloatArray, FloatArray, float]:
    """``J^T W J`` (3k, 3k), ``J^T W r`` (3k,) and the weighted sum of squares, over every pair."""
    normal = np.zeros((3 * count, 3 * count))
    gradient = np.zeros(3 * count)
    total = 0.0
    for m, w in zip(matches, weights, strict=True):
        r, jac_i, jac_j = _jacobians(m, rotations)
        total += float(np.sum(w * np.sum(r * r, axis=1)))
        for k, jac in ((m.i, jac_i), (m.j, jac_j)):
            gradient[3 * k : 3 * k + 3] += np.einsum("n,nki,nk->i", w, jac, r)
            for k2, jac2 in ((m.i, jac_i), (m.j, jac_j)):
                normal[3 * k : 3 * k + 3, 3 * k2 : 3 * k2 + 3] += np.einsum("n,nki,nkj->ij", w, jac, jac2)
    return normal, gradient, total


def _weights(matches: list[Matches], rotations: list[FloatArray]) -> list[FloatArray]:
    """Cauchy weights of each pair's matches at twice its robust sigma; 0 beyond :data:`NEAR_PX`."""
    out = []
    for m in matches:
        r, _, _ = _jacobians(m, rotations)
        norm = np.linalg.norm(r, axis=1)
        loose = NEAR_PX / m.scale_px_per_rad
        close = norm < loose
        sigma = max(mad_sigma(norm[close]) if close.any() else loose, 0.05 / m.scale_px_per_rad)
        out.append(np.where(close, 1.0 / (1.0 + (norm / (2 * sigma)) ** 2), 0.0))
    return out


def _refine(count: int, matches: list[Matches], rotations: list[FloatArray]) -> tuple[list[FloatArray], int]:
    """Gauss-Newton (iteratively reweighted, the weights kept from step :data:`FREEZE_WEIGHTS_STEP` on) on every
    camera's rotation but camera 0's; the steps taken."""
    rs = list(rotations)
    free = slice(3, 3 * count)
    weights: list[FloatArray] = []
    for step in range(1, MAX_STEPS + 1):
        if step <= FREEZE_WEIGHTS_STEP:
            weights = _weights(matches, rs)
        normal, gradient, _ = _normal_equations(count, matches, rs, weights)
        try:
            delta = -np.linalg.solve(normal[free, free], gradient[free])
        except np.linalg.LinAlgError:
            raise PanomapError("the matches do not fix every camera's rotation (singular normal equations)") from None
        for k in range(1, count):
            rs[k] = rotation_from_vector(delta[3 * (k - 1) : 3 * k]) @ rs[k]
        if np.max(np.abs(delta)) < STEP_TOLERANCE_RAD:
            return rs, step
    raise PanomapError(f"the rotations did not converge in {MAX_STEPS} steps")


def _skew_rows(v: FloatArray) -> FloatArray:
    """``[v]x`` (n, 3, 3) of each row of ``v`` (n, 3)."""
    out = np.zeros((len(v), 3, 3))
    out[:, 0, 1], out[:, 0, 2], out[:, 1, 2] = -v[:, 2], v[:, 1], -v[:, 0]
    out[:, 1, 0], out[:, 2, 0], out[:, 2, 1] = v[:, 2], -v[:, 1], v[:, 0]
    return out


def _uncertainty(count: int, matches: list[Matches], rotations: list[FloatArray]) -> tuple[float, ...]:
    """Each camera's 1-sigma rotation uncertainty (deg, its worst axis): ``s^2 (J^T W J)^-1``, ``s^2`` the
    weighted residuals' sum of squares per degree of freedom (two a match); camera 0's is 0."""
    weights = _weights(matches, rotations)
    normal, _, total = _normal_equations(count, matches, rotations, weights)
    dof = sum(2 * int(np.count_nonzero(w)) for w in weights) - 3 * (count - 1)
    covariance = np.linalg.inv(normal[3:, 3:]) * (total / max(dof, 1))
    out = [0.0]
    for k in range(1, count):
        block = covariance[3 * (k - 1) : 3 * k, 3 * (k - 1) : 3 * k]
        out.append(math.degrees(math.sqrt(max(float(np.max(np.linalg.eigvalsh(block))), 0.0))))
    return tuple(out)


def _pair_report(rig: CameraRig, m: Matches, rotations: list[FloatArray]) -> PairReport:
    a, b = m.rays_i @ rotations[m.i].T, m.rays_j @ rotations[m.j].T
    angle = np.arccos(np.clip(np.sum(a * b, axis=1), -1.0, 1.0))
    loose = NEAR_PX / m.scale_px_per_rad
    close = angle < loose
    sigma = mad_sigma(angle[close]) if close.any() else loose
    inlier = angle <= max(3 * sigma, 1.0 / m.scale_px_per_rad)
    near = close & ~inlier
    # px: each ray through the other camera's table, against that camera's feature; the two ways' mean.
    into_j = rig.tables[m.j].sample(*azimuth_elevation(a[inlier])).astype(np.float64) - m.pixels_j[inlier]
    into_i = rig.tables[m.i].sample(*azimuth_elevation(b[inlier])).astype(np.float64) - m.pixels_i[inlier]
    px = (np.linalg.norm(into_j, axis=1) + np.linalg.norm(into_i, axis=1)) / 2
    px = px[np.isfinite(px)]
    degrees = np.degrees(angle[inlier])
    along, across = _along_across(rig, m, a[inlier], b[inlier])

    def pct(values: FloatArray, q: float) -> float:
        return float(np.percentile(values, q)) if values.size else math.nan

    return PairReport(
        (rig.names[m.i], rig.names[m.j]),
        m.count,
        int(inlier.sum()),
        int(near.sum()),
        pct(degrees, 50),
        pct(degrees, 90),
        pct(px, 50),
        pct(px, 90),
        float(np.degrees(np.median(angle[near]))) if near.any() else None,
        pct(along, 90),
        pct(across, 90),
    )


def _along_across(rig: CameraRig, m: Matches, a: FloatArray, b: FloatArray) -> tuple[FloatArray, FloatArray]:
    """The residuals ``b - a`` of world rays (n, 3) along the pair's ring and across it (n,) each, absolute, px at
    the band's scale: across is toward the pole ``a_i - a_j`` of the ring, along is square to it and to the ray."""
    axes = rig.optical_axes()
    pole = axes[m.i] - axes[m.j]
    norm = float(np.linalg.norm(pole))
    if norm < 1e-9:
        nan = np.full(len(a), np.nan)
        return nan, nan
    pole = pole / norm
    tangent = np.cross(pole, a)
    tangent /= np.maximum(np.linalg.norm(tangent, axis=1, keepdims=True), 1e-12)
    r = (b - a) * m.scale_px_per_rad
    return np.abs(np.sum(r * tangent, axis=1)), np.abs(r @ pole)


__all__ = ["Band", "LearnedRig", "OverlapFit", "PairReport", "band_of", "learn_rotations", "turned_table"]
