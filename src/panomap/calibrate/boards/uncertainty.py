"""The projection uncertainty of a camera learned from checkerboards: the corners' noise carried through the fit.

Convention: as :mod:`.fit` (pixels px; rays in the camera's axes, alpha rad from the pole the image centre sees,
phi the image angle); a camera is a radial kind and ``params = [u0, v0, *coefficients]``.

mrcal's method, for this radial camera. The corners' noise sigma (px per coordinate) is the fit's residuals'
over its degrees of freedom, never known beforehand. Residuals of neighbouring corners are correlated on real
boards (0.1-0.7; a detector's bias and what a rotationally symmetric law cannot follow vary smoothly across a
board), and correlated residuals hold fewer independent measurements: sigma^2 is taken ``(1 + c) / (1 - c)``
times, c their correlation along a board's rows and columns (the long-run variance of a sequence whose
neighbours correlate by c; simulated corners with independent noise give c = 0 and the factor 1). The
covariance of every parameter fitted (centre, coefficients, each board's pose)
is ``sigma^2 (J^T J)^-1`` with J the fit's Jacobian; the camera's block of it is its covariance with the poses
marginalised (what they absorbed is in it: a centre moved and every board turned with it explain the corners
nearly as well, and the block says so).

A law chosen from the corners is not taken as known. Boards pin a camera's stretch along its axis (points
``(x, y, s z)``: a board facing the axis is the same squares under every s) only through their perspective,
and a two-parameter law fitted to one board pins it by its form instead; so where the law was chosen (not
given) the stretch is fitted too, in the covariance, and drawn with the rest. Given the law (the simulator's
true one), the band is the noise's alone.

What is "the same ray" under two cameras? Boards pin the camera's shape, not its turn: a rotation of the whole
frame is taken up by their poses, and the table's turn is set apart (the azimuth origin, the tilt from vertical
edges). As the outside checks compare a camera with its calibration, and as mrcal compares in a frame the
boards align: pixels on rings about the centre, each pixel's ray under both cameras, the other's rays turned by
the one rotation that best aligns them (least squares on the rays, over the rings inside the boards' field),
projected back by the camera; the distance (px). Linearised in the camera's parameters this is one linear map
``A`` (pixels' shifts per parameter); draws of the parameters from their covariance, through ``A``, give each
pixel's shifts: its band is their 95th percentile, the ring's band that of the largest shift along the ring
(on simulated boards, the true law given, the true error lies within it at 93.6-94.2% of the rings inside the
field, four conditions of 100-200 sets: ``tests/test_board_uncertainty.py``).

The band is judged inside the boards' field: the angles from the axis between which 90% of the corners lie
(their 5th and 95th percentiles; the outermost corners of one board do not make it).

What it does not cover: a camera that is not rotationally symmetric (two focal lengths, an affine term: the
real sets' calibrations have them, and one board lies 2-4.5 px from them where its band says 1.6-2), and
corners found off alike: the band is the noise's share of the error, not all of it.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from ...camera.radial import RadialFunction
from ...errors import PanomapError
from ...geometry import FloatArray
from ..circles import ImageCircles
from ..core.projection_band import ProjectionBand
from ..lines.agreement import RING_AZIMUTHS, ring_alphas
from ..lines.rays import InverseRadial
from .detect import Board

#: The camera's projection: pixels (n, 2) of points (n, 3) under ``(kind, axis, params)`` (:func:`.fit.project`,
#: handed in: this module is below the fit).
Project = Callable[[str, str, FloatArray, FloatArray], FloatArray]

# Draws of the camera's parameters from their covariance (the 95th percentile's own error: about 2% of it).
DRAWS = 2000
# The draws' seed: the same fit reports the same band.
SEED = 20070601
# Relative step of the central differences (at least this, absolute).
STEP = 1e-6


# The boards' field: the angles from the axis where this share of the corners lie (percentiles).
FIELD_PERCENT = (5.0, 95.0)
# The residuals' neighbour correlation is taken up to this (a smooth field of residuals: the factor 19).
MAX_CORRELATION = 0.9


def board_band(
    project: Project,
    kind: str,
    axis: str,
    params: FloatArray,
    poses: FloatArray,
    points: FloatArray,
    jacobian: FloatArray,
    boards: Sequence[Board],
    circles: ImageCircles,
    sigma_px: float,
    stretch: bool,
) -> ProjectionBand | None:
    """The band of a board fit (:func:`.fit.fit_boards`): the camera ``params`` (p,) under ``project``, the
    boards' ``poses`` (B, 6) and their corners ``points`` (N, 3) in the camera's axes, the Jacobian (2N, p + 6B)
    of the corners' residuals at the fit, the noise ``sigma_px`` per coordinate from its residuals;
    ``stretch``: the camera left free to stretch along its axis (a law chosen, not given). None where the rays
    of the boards' field do not align a frame."""
    observed = np.concatenate([b.pixels for b in boards])
    residuals = project(kind, axis, params, points) - observed
    rho = residual_correlation(residuals, boards)
    factor = (1.0 + rho) / (1.0 - rho)
    count = params.size
    if stretch:
        jacobian = np.column_stack(
            [jacobian[:, :count], stretch_column(project, kind, axis, params, points), jacobian[:, count:]]
        )
    covariance = parameter_covariance(jacobian, sigma_px * math.sqrt(factor))[: count + stretch, : count + stretch]
    alpha = np.arccos(np.clip(points[:, 2] / np.linalg.norm(points, axis=1), -1.0, 1.0))
    reach = reach_alpha(kind, axis, params, circles, float(alpha.max()))
    try:
        return projection_band(
            project,
            kind,
            axis,
            params,
            covariance,
            (float(np.percentile(alpha, FIELD_PERCENT[0])), float(np.percentile(alpha, FIELD_PERCENT[1]))),
            reach,
            sigma_px=sigma_px,
            corners=len(observed),
            boards=len(boards),
            parameters=int(params.size + poses.size),
            stretch=stretch,
            correlation=rho,
        )
    except PanomapError:
        return None


def residual_correlation(residuals: FloatArray, boards: Sequence[Board]) -> float:
    """The correlation of the residuals (N, 2) px of neighbouring corners (next along a board's row or column),
    both coordinates pooled, clipped to [0, ``MAX_CORRELATION``]."""
    first, second = [], []
    start = 0
    for board in boards:
        own = residuals[start : start + len(board.pixels)]
        start += len(board.pixels)
        place = {(int(c), int(r)): k for k, (c, r) in enumerate(board.grid)}
        for (c, r), k in place.items():
            for step in ((c + 1, r), (c, r + 1)):
                j = place.get(step)
                if j is not None:
                    first.append(own[k])
                    second.append(own[j])
    if not first:
        return 0.0
    a, b = np.asarray(first), np.asarray(second)
    a, b = a - residuals.mean(axis=0), b - residuals.mean(axis=0)
    rho = float(np.sum(a * b) / math.sqrt(float(np.sum(a * a) * np.sum(b * b)) or 1.0))
    return min(max(rho, 0.0), MAX_CORRELATION)


def stretch_column(project: Project, kind: str, axis: str, params: FloatArray, points: FloatArray) -> FloatArray:
    """The corners' pixels' change (2N,) px per unit stretch of the camera along its axis (points ``(x, y, s z)``,
    at s = 1), in the residuals' order (u, v of each corner)."""
    up, down = points.copy(), points.copy()
    up[:, 2] *= 1.0 + STEP
    down[:, 2] *= 1.0 - STEP
    return np.asarray(((project(kind, axis, params, up) - project(kind, axis, params, down)) / (2 * STEP)).ravel())


def parameter_covariance(jacobian: FloatArray, sigma_px: float) -> FloatArray:
    """``sigma^2 (J^T J)^-1`` (P, P) of the parameters of a least-squares fit whose Jacobian is ``jacobian``
    (R, P), the columns scaled to unit length first (the coefficients and poses span orders of magnitude: the
    pseudo-inverse then drops only what no residual sees)."""
    norms = np.linalg.norm(jacobian, axis=0)
    norms = np.where(norms > 0, norms, 1.0)
    scaled = jacobian / norms
    return np.asarray(np.linalg.pinv(scaled.T @ scaled, hermitian=True) / np.outer(norms, norms) * sigma_px**2)


def projection_band(
    project: Project,
    kind: str,
    axis: str,
    params: FloatArray,
    covariance: FloatArray,
    field_alpha: tuple[float, float],
    reach_alpha: float,
    *,
    sigma_px: float,
    corners: int,
    boards: int,
    parameters: int,
    stretch: bool = False,
    correlation: float = 0.0,
) -> ProjectionBand:
    """The 95% band of the camera ``params`` (p,) under ``project``, whose covariance (p, p) is ``covariance``
    (the poses marginalised), on the rings of :func:`..lines.agreement.ring_alphas` up to ``reach_alpha`` (rad), the
    rotation aligned over the rings inside ``field_alpha`` (rad, the corners' angles from the axis). With
    ``stretch`` the last row and column of ``covariance`` are the stretch's (:func:`stretch_column`).

    ``sigma_px``, ``corners``, ``boards``, ``parameters`` and ``correlation`` are what the band reports of the
    fit.
    """
    alpha = ring_alphas(reach_alpha)
    field_deg = (math.degrees(field_alpha[0]), math.degrees(field_alpha[1]))
    phi = np.linspace(0.0, 2.0 * math.pi, RING_AZIMUTHS, endpoint=False)
    draft = ProjectionBand(
        tuple(np.degrees(alpha).tolist()), tuple(np.degrees(phi).tolist()), (), (), field_deg, sigma_px, 0, 0, 0
    )
    aligned = draft.inside()
    shifts = shift_map(project, kind, axis, params, alpha, phi, aligned, stretch)  # (m, k, 2, p)
    draws = parameter_draws(covariance, DRAWS)  # (p, DRAWS)
    pixel_band = np.empty((alpha.size, phi.size))
    ring_band = np.empty(alpha.size)
    rank = math.ceil(0.95 * DRAWS) - 1  # the 95th percentile: the draw of this rank
    for i in range(alpha.size):  # one product a ring (a (2, p) product per pixel took twice as long; the same values)
        moved = (shifts[i].reshape(-1, shifts.shape[-1]) @ draws).reshape(phi.size, 2, DRAWS)
        pixel_band[i], ring_band[i] = ranked_lengths(moved, rank)
    pixel_band = np.where(np.isfinite(pixel_band), pixel_band, np.inf)
    ring_band = np.where(np.isfinite(ring_band), ring_band, np.inf)
    return ProjectionBand(
        alpha_deg=draft.alpha_deg,
        azimuth_deg=draft.azimuth_deg,
        pixel_band_px=tuple(tuple(float(x) for x in row) for row in pixel_band),
        ring_band_px=tuple(float(x) for x in ring_band),
        field_deg=field_deg,
        sigma_px=sigma_px,
        corners=corners,
        boards=boards,
        parameters=parameters,
        correlation=correlation,
        stretch=stretch,
    )


def parameter_draws(covariance: FloatArray, count: int) -> FloatArray:
    """``count`` draws (p, count) of a zero-mean normal with ``covariance`` (p, p), from :data:`SEED`, through its
    symmetric square root (V sqrt(L) V^T): unique, so the draws move continuously with the covariance, where
    V sqrt(L) alone turns with eigh's choice of basis wherever eigenvalues nearly tie (a 1e-10 change of the fit
    moved the band by up to 6%)."""
    values, vectors = np.linalg.eigh((covariance + covariance.T) / 2)
    root = (vectors * np.sqrt(np.clip(values, 0.0, None))) @ vectors.T
    return np.asarray(root @ np.random.default_rng(SEED).standard_normal((covariance.shape[0], count)))


def ranked_lengths(moved: FloatArray, rank: int) -> tuple[FloatArray, float]:
    """The ``rank``-th smallest length (px) of the shifts ``moved`` (k, 2, D) px (k pixels, D draws) over the draws:
    at each pixel (k,), and of each draw's longest over the pixels (a ring's).

    The draws are ranked by their squared lengths (a partition, not a sort; its values, not their places: half the
    time of ranking their places) and only the ring's picked draw measured again (``hypot``): ``hypot`` over every
    draw was half the band's time. Each draw's longest is the largest of its squared lengths (a reduction over the
    pixels, which its place along them, ``argmax`` across the rows, took four times as long to find); the pixel of
    the draw picked is then found along that draw alone. The same lengths (to 1e-15 of them).
    """
    squared = moved[:, 0] ** 2 + moved[:, 1] ** 2  # (k, D)
    at_pixels = np.sqrt(np.partition(squared, rank, axis=1)[:, rank])
    draw = int(np.argpartition(squared.max(axis=0), rank)[rank])  # the draw whose longest shift is of that rank
    widest = int(np.argmax(squared[:, draw]))  # the pixel it moves most
    return at_pixels, float(np.hypot(moved[widest, 0, draw], moved[widest, 1, draw]))


def shift_map(
    project: Project,
    kind: str,
    axis: str,
    params: FloatArray,
    alpha: FloatArray,
    phi: FloatArray,
    aligned: FloatArray,
    stretch: bool = False,
) -> FloatArray:
    """The linear map (m, k, 2, p) from a change of the camera's parameters (p,; with ``stretch`` the stretch
    along its axis last) to the shift (px) of its pixel of each ray on rings ``alpha`` (m,) rad at azimuths
    ``phi`` (k,) rad, after the rotation that best aligns the rays over the rings ``aligned`` (m,) bool (least
    squares on the rays: each pixel's shift weighed by the ray's turn per px, radially ``1 / f_r'``, along the
    ring ``sin(alpha) / r``)."""
    sin_a, cos_a = np.sin(alpha)[:, None], np.cos(alpha)[:, None]
    rays = np.stack(np.broadcast_arrays(sin_a * np.cos(phi), sin_a * np.sin(phi), cos_a), axis=-1).reshape(-1, 3)
    count = params.size + stretch
    by_param = np.empty((rays.shape[0], 2, count))
    if stretch:
        by_param[:, :, -1] = stretch_column(project, kind, axis, params, rays).reshape(-1, 2)
    for j in range(params.size):
        step = STEP * max(1.0, abs(float(params[j])))
        up, down = params.copy(), params.copy()
        up[j] += step
        down[j] -= step
        by_param[:, :, j] = (project(kind, axis, up, rays) - project(kind, axis, down, rays)) / (2 * step)
    by_turn = np.empty((rays.shape[0], 2, 3))
    for j in range(3):
        turn = np.zeros(3)
        turn[j] = STEP
        by_turn[:, :, j] = (
            project(kind, axis, params, rays + np.cross(turn, rays))
            - project(kind, axis, params, rays - np.cross(turn, rays))
        ) / (2 * STEP)
    metric = _ray_metric(kind, axis, params, alpha, phi).reshape(-1, 2, 2)
    chosen = np.repeat(np.asarray(aligned, dtype=bool), phi.size)
    ok = chosen & np.all(np.isfinite(by_param), axis=(1, 2)) & np.all(np.isfinite(by_turn), axis=(1, 2))
    weighed = np.einsum("nab,nbc->nac", metric[ok], by_turn[ok])  # M W
    normal = np.einsum("nab,nac->bc", by_turn[ok], weighed)  # sum W^T M W (3, 3)
    right = np.einsum("nab,nac->bc", weighed, by_param[ok])  # sum W^T M P (3, p)
    if not ok.any() or np.linalg.matrix_rank(normal) < 3:
        raise PanomapError("the boards' field holds too few rays to align the camera's frame")
    turn_of = np.linalg.solve(normal, right)  # the best rotation per parameter (3, p)
    shift = by_param - by_turn @ turn_of
    return np.asarray(shift.reshape(alpha.size, phi.size, 2, count), dtype=np.float64)


def _ray_metric(kind: str, axis: str, params: FloatArray, alpha: FloatArray, phi: FloatArray) -> FloatArray:
    """Per pixel (m, k, 2, 2): the squared turn of the ray (rad^2) per squared shift of the pixel (px^2)."""
    from ...camera.radial_models import rho_of_alpha

    radial = RadialFunction(kind, _radial_coefficients(kind, params), axis)
    step = 1e-5
    radius = np.abs(radial(rho_of_alpha(alpha, axis)))
    slope = (np.abs(radial(rho_of_alpha(alpha + step, axis))) - np.abs(radial(rho_of_alpha(alpha - step, axis)))) / (
        2 * step
    )
    radial_weight = 1.0 / np.maximum(slope, 1e-9) ** 2  # (m,)
    along_weight = (np.sin(alpha) / np.maximum(radius, 1e-9)) ** 2
    e_r = np.stack([np.cos(phi), np.sin(phi)], axis=-1)  # (k, 2)
    e_t = np.stack([-np.sin(phi), np.cos(phi)], axis=-1)
    outer_r = e_r[:, :, None] * e_r[:, None, :]
    outer_t = e_t[:, :, None] * e_t[:, None, :]
    return np.asarray(
        radial_weight[:, None, None, None] * outer_r[None] + along_weight[:, None, None, None] * outer_t[None]
    )


def _radial_coefficients(kind: str, params: FloatArray) -> tuple[float, ...]:
    """The radial law's coefficients among the camera's ``params`` (u0, v0, coefficients, then any image terms':
    the ray metric and the reach read the radial law alone)."""
    from ...camera.radial_models import radial_kind

    return tuple(float(c) for c in params[2 : 2 + radial_kind(kind).parameter_count])


def reach_alpha(kind: str, axis: str, params: FloatArray, circles: ImageCircles, corners_alpha: float) -> float:
    """The angle (rad) from the axis up to which the band is told: the image circle's rim where the frame shows it
    and the camera reaches it, else the farthest corner."""
    if circles.rim_in_frame <= 0:
        return corners_alpha
    radial = RadialFunction(kind, _radial_coefficients(kind, params), axis)
    try:
        alpha, _ = InverseRadial.of(radial, circles.outer_radius)(np.array([circles.outer_radius]))
    except PanomapError:
        return corners_alpha
    return max(float(alpha[0]), corners_alpha) if np.isfinite(alpha[0]) else corners_alpha
