"""Two lenses a little apart: their tilt bounded by the far matches, their roll by the parallax-free components.

Convention (docs/conventions.md, "A rig"; :mod:`panomap.rig.learn`): rotations take a camera's axes to the world's,
updated as ``R -> exp(w) R`` (``w`` a world rotation vector, rad); rays are unit (3,) world vectors.

**The physics.** A point P seen from both lenses' centres ``c_i``, ``c_j`` gives world rays ``a`` (camera i) and
``b`` (camera j) whose difference is its parallax: ``a - b ~ (c_j - c_i)_perp / depth``, ``_perp`` the part
square to the ray. So each match's residual ``r = a - b`` splits in two: along ``e``, the unit direction of
``(c_j - c_i)_perp`` at ``a`` (the epipolar great circle's), a parallax ``p = r . e >= 0`` (0 for a far point, up
to ``|c_j - c_i| / depth``), never negative but for noise; square to it (``n = r . (a x e)``) nothing but the
cameras' own errors. Where the rig does not say where the centres are (a camchain's ``t`` 0), a 360 camera's
lenses sit back to back, each ahead of the other along its own axis: ``c_i - c_j`` along ``axis_i - axis_j``.

For two lenses back to back the overlap is a ring about the baseline: ``n`` is the along-ring component, and
pins the **roll** about the baseline (which moves no match across the ring); ``p`` is the across-ring one, and a
**tilt** of camera j (a turn square to the baseline) moves it in a +-cos pattern round the ring, which parallax
can mimic (a nearer wall on one side than the other). Least squares on ``r`` reads such parallax as a tilt
(the demo's dual fisheye in the bundled room, lenses 2 cm apart: 0.89 deg off, 0.10 deg stated). Here
(:func:`settle`):

* the **epipolar fit** (:func:`epipolar_fit`): the ``n`` components alone; off the ring they turn with the tilt
  too (by the tangent of the match's latitude off it), which pins it loosely, whatever the parallax;
* the **feasible tilts** (:func:`bound_tilt`, :func:`feasible_tilts`): within three sigmas of the epipolar
  fit's tilt (its covariance not averaged over the matches: their small common errors moved it 0.16 deg on the
  room where averaging stated 0.026), at which every match's ``p`` is at least ``-TAU_SIGMAS sigma`` (``sigma``:
  the ``n`` components' robust spread; all but :data:`SPARE_FRACTION` of them: mismatches) and each of the
  ring's :data:`SECTORS` sectors' median ``p`` at least ``-TAU_SIGMAS`` its median's noise (``sqrt(pi / 2) sigma /
  sqrt(m)``): the truth is among them but where the noise passes three sigmas. Far matches all round the ring
  hem the set in tightly (a sector of them pins its median to a fraction of a px); near ones from one side only;
* the **answer**: the least squares' turn, whole, where its tilt is feasible; else the feasible tilt nearest it,
  and the roll fitted again to the ``n`` components alone. The **bound**: the farthest feasible tilt from the
  answer, and three sigmas of the roll (``ParallaxFit.bound_deg``).

A bound within :data:`PINNED_DEG`: pinned; beyond it the answer stands with its bound, and the report says what
would pin it. Where the set reaches :data:`MAX_TILT_DEG` (not bounded) or is empty (:class:`Inconsistent`: a
lens's calibration off, as a focal length 1% long, puts the parallax below zero all round), the least squares'
turn stands and the report says "NOT BOUNDED" and why.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..camera.orientation import rotation_from_vector
from ..errors import PanomapError
from ..geometry import FloatArray
from ..robust import mad_sigma

#: The noise allowed below zero parallax, in sigmas, for each match and for each sector's median.
TAU_SIGMAS = 3.0
#: A median's noise in the sigmas of its values' noise, times sqrt(count) (normal values: sqrt(pi / 2)).
MEDIAN_SIGMAS = math.sqrt(math.pi / 2)
#: Matches allowed below that at a feasible tilt (mismatches a ratio test lets through): this fraction, at least
#: :data:`MIN_SPARE`.
SPARE_FRACTION = 0.1
MIN_SPARE = 3
#: The ring cut in this many sectors for the medians; a sector needs :data:`MIN_SECTOR` matches to count.
SECTORS = 12
MIN_SECTOR = 5
#: A tilt bounded within this (deg) is pinned; beyond, the report says the overlap lacks far objects.
PINNED_DEG = 0.1
#: The tilts searched (deg each way); a feasible set reaching this far is not bounded: refused.
MAX_TILT_DEG = 4.0
#: The grid's points each way (odd), and the feasible set's width (in grid steps) below which the grid is refined.
GRID = 41
FINE_STEPS = 12
#: The epipolar fit's cut-offs (sigmas), wide to narrow.
ANNEAL = (24.0, 12.0, 6.0, 3.0)
#: Passes of tilt then roll.
PASSES = 3
#: Robust sigma at least this (px at the band's scale).
MIN_SIGMA_PX = 0.05


class Inconsistent(PanomapError):
    """No tilt lets every match's parallax be at least zero within the noise: the model does not hold."""


@dataclass(frozen=True)
class ParallaxFit:
    """How far camera j's tilt is pinned by the far matches of its pair (:func:`settle`).

    ``matches``: those used (within :data:`~panomap.rig.learn.NEAR_PX` and square to their epipolar circle within
    ``TAU_SIGMAS`` sigma); ``far``: those whose parallax is within the noise at the answer; ``sigma_px``: the
    parallax-free components' robust sigma (px at the band's scale); ``parallax_px_p90``: the matches' parallax
    p90 (px); ``tilt_bound_deg``: the farthest feasible tilt from the answer; ``roll_sigma_deg``: the roll's
    1-sigma; ``moved_deg``: how far the answer is from the least squares on the whole residual; ``pinned``: the
    tilt bound within :data:`PINNED_DEG`; ``assumed_baseline``: the rig's cameras at one point, so the baseline
    was taken along the axes (lenses back to back)."""

    cameras: tuple[str, str]
    matches: int
    far: int
    sigma_px: float
    parallax_px_p90: float
    tilt_bound_deg: float
    roll_sigma_deg: float
    moved_deg: float
    pinned: bool
    assumed_baseline: bool
    unbounded: bool = False
    why: str = ""

    @property
    def bound_deg(self) -> float:
        """The rotation's bound (deg): the tilt's bound and three sigmas of the roll, added in quadrature."""
        return math.hypot(self.tilt_bound_deg, 3 * self.roll_sigma_deg)

    def describe(self) -> tuple[str, str]:
        """Two lines: the figures, then what they pin of the tilt (indented)."""
        where = "the lenses' centres taken along their axes" if self.assumed_baseline else "the rig's lens centres"
        figures = (
            f"{self.cameras[0]} and {self.cameras[1]}, parallax ({where}): {self.matches} matches"
            + ("" if self.unbounded else f", {self.far} far")
            + f", parallax p90 {self.parallax_px_p90:.2f} px (noise {self.sigma_px:.2f} px)"
        )
        roll = f"roll 1-sigma {self.roll_sigma_deg:.4f} deg"
        if self.unbounded:
            return figures, f"  tilt NOT BOUNDED (the features' least squares, moved by parallax); {self.why}; {roll}"
        tilt = f"tilt within {self.tilt_bound_deg:.3f} deg, {roll}, moved {self.moved_deg:.3f} deg from least squares"
        if self.pinned:
            return figures, f"  {tilt}"
        far = "a picture with far objects in the overlap pins it"
        return figures, f"  {tilt}; not pinned (over {PINNED_DEG:g} deg): {far}"


def baseline_of(
    axis_i: FloatArray, axis_j: FloatArray, centre_i: FloatArray, centre_j: FloatArray
) -> tuple[FloatArray, bool]:
    """The unit direction (3,) of ``c_j - c_i`` (world); where the centres coincide, ``axis_j - axis_i`` (each lens
    ahead of the other along its own axis); and whether it was so assumed."""
    between = np.asarray(centre_j, np.float64) - np.asarray(centre_i, np.float64)
    assumed = float(np.linalg.norm(between)) < 1e-9
    if assumed:
        between = np.asarray(axis_j, np.float64) - np.asarray(axis_i, np.float64)
    return between / np.linalg.norm(between), assumed


@dataclass(frozen=True)
class Components:
    """The matches' residuals ``a - b`` split about their epipolar circles (:func:`components`), world frame.

    ``p`` (n,): the parallax components (rad, along ``e``); ``n`` (n,): the parallax-free ones (rad, along
    ``a x e``); ``gp``, ``gn`` (n, 3): their gradients in camera j's turn ``w`` (a world rotation vector, rad:
    ``p(w) = p - gp w``, likewise ``n``); ``lon_rad`` (n,): each match's longitude about the baseline."""

    p: FloatArray
    n: FloatArray
    gp: FloatArray
    gn: FloatArray
    lon_rad: FloatArray


def components(a: FloatArray, b: FloatArray, baseline: FloatArray) -> Components:
    """The parallax and parallax-free components of the residuals ``a - b`` (module docstring) of camera i's
    world rays ``a`` (n, 3) and camera j's ``b`` (n, 3), ``baseline`` (3,) the unit direction of ``c_j - c_i``."""
    e = baseline[None, :] - (a @ baseline)[:, None] * a
    e /= np.maximum(np.linalg.norm(e, axis=1, keepdims=True), 1e-12)
    m = np.cross(a, e)
    r = a - b
    u1, u2 = _square_to(baseline)
    lon_rad = np.arctan2(a @ u2, a @ u1)
    return Components(np.sum(r * e, axis=1), np.sum(r * m, axis=1), np.cross(b, e), np.cross(b, m), lon_rad)


def _square_to(axis: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Two unit vectors (3,) square to ``axis`` and to each other."""
    u1 = np.cross(axis, [0.0, 0.0, 1.0] if abs(axis[2]) < 0.9 else [1.0, 0.0, 0.0])
    u1 /= np.linalg.norm(u1)
    return u1, np.cross(axis, u1)


def feasible_tilts(p: FloatArray, gp: FloatArray, lon_rad: FloatArray, sigma: float, tilts: FloatArray) -> FloatArray:
    """Which of ``tilts`` (k, 3; world rotation vectors of camera j, rad, square to the baseline) are feasible
    (k,) bool (module docstring): each match's ``p - Gp w`` (``p`` (n,), ``gp`` (n, 3), rad) at least
    ``-TAU_SIGMAS sigma`` (``sigma`` rad) but for the spare ones, each sector of longitudes ``lon_rad`` (n,)
    its median at least ``-TAU_SIGMAS`` its noise."""
    moved = p[None, :] - tilts @ gp.T  # (k, n)
    spare = max(MIN_SPARE, math.ceil(SPARE_FRACTION * len(p)))
    broken = np.sum(moved < -TAU_SIGMAS * sigma, axis=1)
    sector = np.floor(np.mod(lon_rad, 2 * math.pi) / (2 * math.pi) * SECTORS).astype(int)
    for s in range(SECTORS):
        inside = sector == s
        count = int(inside.sum())
        if count >= MIN_SECTOR:
            floor = -TAU_SIGMAS * MEDIAN_SIGMAS * sigma / math.sqrt(count)
            broken = broken + (spare + 1) * (np.median(moved[:, inside], axis=1) < floor)
    return np.asarray(broken <= spare)


def bound_tilt(
    p: FloatArray,
    gp: FloatArray,
    lon_rad: FloatArray,
    sigma: float,
    basis: FloatArray,
    tilt_n: FloatArray,
    cov_n: FloatArray,
) -> tuple[FloatArray, float]:
    """The feasible tilts (k, 2) (rad, in ``basis`` (2, 3): two world rotation vectors square to the baseline), on
    a grid, and its step (rad). The set: the
    tilts within three sigmas of the parallax-free components' own (``tilt_n`` (2,), covariance ``cov_n`` (2, 2))
    that the parallax allows (:func:`feasible_tilts`).
    The grid's half-width grows until the set lies inside it, and narrows about the set until a step is a
    twelfth of it.

    Raises PanomapError where the set reaches :data:`MAX_TILT_DEG`; :class:`Inconsistent` where it is empty."""
    inverse = np.linalg.inv(cov_n)
    half = max(4 * sigma, 1e-5)
    centre = np.asarray(tilt_n, np.float64)
    limit = math.radians(MAX_TILT_DEG)
    ticks = np.linspace(-1.0, 1.0, GRID)
    grid = np.stack(np.meshgrid(ticks, ticks, indexing="ij"), axis=-1).reshape(-1, 2)
    for _ in range(60):
        points = centre + half * grid
        offset = points - tilt_n
        inside = np.einsum("ki,ij,kj->k", offset, inverse, offset) <= TAU_SIGMAS**2
        step = 2 * half / (GRID - 1)
        if not inside.any():
            centre, half = np.asarray(tilt_n, np.float64), half / 2
            continue
        ok = np.zeros(len(points), dtype=bool)
        ok[inside] = feasible_tilts(p, gp, lon_rad, sigma, points[inside] @ basis)
        inner = points[ok]
        if not len(inner):
            extent = TAU_SIGMAS * math.sqrt(float(np.max(np.linalg.eigvalsh(cov_n))))
            if step <= extent / GRID or half >= limit:
                raise Inconsistent(
                    "parallax below zero at every tilt: the lenses' calibrations (focal length, centre) or the rig's "
                    "lens centres are off"
                )
            centre, half = np.asarray(tilt_n, np.float64), min(max(extent, 2 * half), limit)
            continue
        if np.any(np.max(np.abs(inner - centre), axis=1) >= half - step / 2):
            if half >= limit:
                raise PanomapError(
                    f"no bound within {MAX_TILT_DEG:g} deg (matches all near, or along one line); a picture with far "
                    "objects all round the overlap pins it"
                )
            centre, half = (inner.max(axis=0) + inner.min(axis=0)) / 2, min(2 * half, limit)
            continue
        width = float(np.max(inner.max(axis=0) - inner.min(axis=0)))
        if width < FINE_STEPS * step and half > 1e-7:
            centre, half = (inner.max(axis=0) + inner.min(axis=0)) / 2, max(width, step)
            continue
        return inner, step
    raise PanomapError("the tilt's feasible set did not settle on a grid")  # pragma: no cover


def epipolar_fit(n: FloatArray, gn: FloatArray, sigma: float) -> tuple[FloatArray, FloatArray, NDArray[np.bool_]]:
    """Camera j's turn ``w`` (k,) (rad; ``gn`` (n, k): its three axes, or the roll's alone) that best zeroes the
    parallax-free components ``n - Gn w``, its covariance (k, k) (``s^2 (Gn^T W Gn)^-1``, ``s^2`` the weighted
    residuals' sum of squares per degree of freedom) and the matches kept (n,) bool. Off the ring these
    components turn with the tilt too (by ``tan`` of the match's latitude off it), so they pin the tilt, loosely,
    whatever the parallax. Robustly, from wide to narrow: the matches within :data:`ANNEAL` sigmas of the fit so
    far, Cauchy weights at half that, down to three sigmas (a start tilted by a fraction of a degree moves the
    matches off the ring by more than three sigmas)."""
    w = np.zeros(gn.shape[1])
    kept = np.ones(len(n), dtype=bool)
    weights = np.ones(len(n))
    for width in ANNEAL:
        for _ in range(5):
            residual = n - gn @ w
            kept = np.abs(residual) <= width * sigma
            weights = np.where(kept, 1.0 / (1.0 + (residual / (width / 2 * sigma)) ** 2), 0.0)
            normal = gn.T @ (gn * weights[:, None])
            w = w + np.linalg.solve(normal, gn.T @ (weights * residual))
    residual = n - gn @ w
    kept = np.abs(residual) <= ANNEAL[-1] * sigma
    weights = np.where(kept, 1.0 / (1.0 + (residual / (2 * sigma)) ** 2), 0.0)
    normal = gn.T @ (gn * weights[:, None])
    scale = float(np.sum(weights * residual**2)) / max(int(kept.sum()) - gn.shape[1], 1)
    return w, np.asarray(np.linalg.inv(normal) * scale, np.float64), kept


def _pick(inner: FloatArray, step: float, fitted: FloatArray) -> tuple[FloatArray, float, bool]:
    """The tilt (2,) among the feasible ones ``inner`` (k, 2) nearest the least squares' (``fitted``), the distance
    from it to the farthest feasible tilt plus a grid step (rad), and whether that is within :data:`PINNED_DEG`.

    Nearest the least squares' rather than the start's where the set is wide: on renders of a room (lenses 0-2 cm
    apart, starts 0.9-1.1 deg off) the least squares' was as near the truth or nearer (median 0.01-0.79 deg by
    baseline, the start's kept 0.27-0.74 deg), and either way the bound holds the truth."""
    best = inner[int(np.argmin(np.linalg.norm(inner - fitted, axis=1)))]
    bound = float(np.max(np.linalg.norm(inner - best, axis=1))) + step
    return best, bound, bound <= math.radians(PINNED_DEG)


def _robust_sigma(values: FloatArray, least: float) -> float:
    """The spread of ``values`` (n,) about 0 among many outliers (a room's repeated textures mismatch half its
    features): :func:`~panomap.robust.mad_sigma`, again among those within three of it, three times."""
    sigma = mad_sigma(values) if values.size else least
    for _ in range(3):
        inside = np.abs(values) <= TAU_SIGMAS * sigma
        if inside.sum() < 2 * MIN_SECTOR:
            break
        sigma = mad_sigma(values[inside])
    return max(sigma, least)


def _roll_sigma(roll_cov: FloatArray, scale_px_per_rad: float) -> float:
    """The roll's 1-sigma (rad) from its fit's covariance (1, 1) (rad^2), with a floor of :data:`MIN_SIGMA_PX`
    for what is common to the matches (which averaging over them does not lessen)."""
    return math.hypot(math.sqrt(max(float(roll_cov[0, 0]), 0.0)), MIN_SIGMA_PX / scale_px_per_rad)


@dataclass(frozen=True)
class Settled:
    """What :func:`settle` found: camera j's ``rotation`` (3, 3); ``tilt_bound_rad`` (inf where the matches do not
    bound it: the least squares' tilt kept, ``unbounded``); ``roll_sigma_rad``; ``sigma_rad``: the parallax-free
    components' robust sigma; ``parallax_rad`` (n,): the matches' parallax at the answer; ``far``: how many of them
    lie within ``TAU_SIGMAS`` sigma of none; ``pinned``: the tilt bounded within :data:`PINNED_DEG`."""

    rotation: FloatArray
    tilt_bound_rad: float
    roll_sigma_rad: float
    sigma_rad: float
    parallax_rad: FloatArray
    far: int
    pinned: bool
    unbounded: bool
    why: str = ""


def settle(
    a_rays: FloatArray,
    b_rays: FloatArray,
    rotation_j: FloatArray,
    baseline: FloatArray,
    scale_px_per_rad: float,
    near_rad: float,
) -> Settled:
    """Camera j's rotation bounded by its pair's matches (module docstring): ``a_rays`` (n, 3) camera i's world
    rays, ``b_rays`` (n, 3) camera j's in its own axes, ``rotation_j`` (3, 3) the least squares' rotation, kept
    whole where its tilt is feasible, else turned to the feasible tilt nearest it and the roll fitted again. Where
    the matches do not bound the tilt (too few on their epipolar circles, none feasible, or the set reaching
    :data:`MAX_TILT_DEG`), the least squares' turn stands, ``unbounded``, and ``why`` says why."""
    rotation = np.asarray(rotation_j, np.float64)
    bound = roll_sigma = sigma = math.nan
    pinned = unbounded = False
    why = ""
    u1, u2 = _square_to(baseline)
    basis = np.stack([u1, u2])
    p = np.zeros(0)
    for _ in range(PASSES):
        b = b_rays @ rotation.T
        split = components(a_rays, b, baseline)
        p, n, gp, gn = split.p, split.n, split.gp, split.gn
        close = np.linalg.norm(a_rays - b, axis=1) < near_rad
        sigma = _robust_sigma(n[close], MIN_SIGMA_PX / scale_px_per_rad)
        try:
            w, cov, kept = epipolar_fit(n[close], gn[close], sigma)
        except np.linalg.LinAlgError:
            kept = np.zeros(int(close.sum()), dtype=bool)
        used = np.flatnonzero(close)[kept]
        if len(used) < 2 * MIN_SECTOR:
            why = f"{len(used)} matches lie on their epipolar circles, too few to bound the tilt"
            return Settled(rotation, math.inf, math.nan, sigma, np.zeros(0), 0, False, True, why)
        # The tilt's ellipse not averaged over the matches: their small systematic errors (0.04 px on a room's
        # renders, a lens's calibration on real ones) are common to them, and this fit's tilt is weak (on the room,
        # 0.16 deg off where averaging stated 0.026).
        cov_tilt = basis @ cov @ basis.T * len(used)
        try:
            inner, step = bound_tilt(p[used], gp[used], split.lon_rad[used], sigma, basis, basis @ w, cov_tilt)
            tilt, bound, pinned = _pick(inner, step, np.zeros(2))
            unbounded, why = False, ""
        except PanomapError as error:
            # Not bounded, or the parallax's model does not hold: the least squares' tilt stands, said so.
            tilt, bound, pinned, unbounded, why = np.zeros(2), math.inf, False, True, str(error)
        if float(np.linalg.norm(tilt)) <= (0.0 if unbounded else step):
            # The least squares' tilt is feasible (or stands): its turn is kept whole, roll too; only bounded here.
            _, roll_cov, _ = epipolar_fit(n[close], (gn[close] @ baseline)[:, None], sigma)
            roll_sigma = _roll_sigma(roll_cov, scale_px_per_rad)
            p = p[used]
            break
        # The roll given the tilt: the parallax-free components fitted again by the roll alone; its 1-sigma
        # averaged, with a floor of MIN_SIGMA_PX for what is common to the matches.
        along = n[close] - gn[close] @ (tilt @ basis)
        roll_w, roll_cov, _ = epipolar_fit(along, (gn[close] @ baseline)[:, None], sigma)
        roll = float(roll_w[0])
        roll_sigma = _roll_sigma(roll_cov, scale_px_per_rad)
        rotation = rotation_from_vector(tilt @ basis + roll * baseline) @ rotation
        p = p[used] - gp[used] @ (tilt @ basis)
    far = int(np.sum(p < TAU_SIGMAS * sigma))
    return Settled(rotation, bound, roll_sigma, sigma, p, far, pinned, unbounded, why)


__all__ = [
    "Components",
    "Inconsistent",
    "ParallaxFit",
    "Settled",
    "baseline_of",
    "bound_tilt",
    "components",
    "epipolar_fit",
    "feasible_tilts",
    "settle",
]
