"""Two cameras' overlap compared tile by tile, and the turn (and one lens's centre) it asks for.

Convention (docs/conventions.md, "A rig"; :mod:`panomap.rig.learn`): rotations take a camera's axes to the world's,
updated as ``R -> exp(w) R`` (``w`` a rotation vector, rad); pixels (u, v) with the top-left pixel's centre at (0, 0);
a band's pixels (x, y) as :class:`~panomap.rig.learn.Band` says (its scale: the cameras' finest in the overlap, so
a band px is about a picture px). Shifts are in band px.

The overlap's **tiles** (:func:`overlap_tiles`): the ring of directions both cameras see (:func:`band_of`, no
margin) drawn from each camera through its table, cut in square tiles; each tile both see whole and textured in
both gives the shift ``s`` (2,) at which camera j's drawing shows what camera i's shows at the tile: by phase
correlation (the side-by-side check's, :mod:`panomap.calibrate.dual_fisheye`), which on tiles this small
understates shifts of a px or more (a 2.25 px turn read 0.2-1.9 px on 32 px tiles of the Ricoh Theta's overlap),
or by normalised cross-correlation within a search (what :func:`learn_with_overlap` uses: 2.2 px read there).

**What a tile's shift says** (camera i right, a far scene): turning camera j by ``w`` and moving its picture by
``c`` (px; the table's pixels ``+ c``, a decentering of its centre) shift the tile by ``H [d]x w + G^-1 c``:
``d`` the tile's world ray, ``H`` (2, 3) the band's px per change of ray, ``G`` (2, 2) camera j's picture px per
band px there (:func:`tile_jacobians`; within 0.15 px of the measured change for 2 px moves and 0.2 deg turns on
the Theta). A turn of j tilts the ring across the band and rolls it along; a centre moved by ``c`` moves the rim
along the ring by ``c``'s tangential part, in a cos pattern round it, which no turn makes. Near objects' parallax
(the lenses' centres apart along their axes) is across the band only.

:func:`learn_with_overlap` fits the shifts along the ring by a roll alone and by a roll and the centre's move, and
keeps the move only where it predicts tiles it was not fitted on (the ring cut in :data:`SECTORS` sectors, each
predicted from the others, :func:`sector_residuals`) clearly better than the roll alone.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import cv2
import numpy as np

from ..errors import PanomapError
from ..geometry import FloatArray, azimuth_elevation
from ..robust import mad_sigma
from ..table.table import PanoMappingTable, fill_entries
from .learn import Band, LearnedRig, OverlapFit, _shots, _skew_rows, band_of, learn_rotations, turned_table
from .rig import CameraRig

#: Tiles (px, square; every half of it) when :func:`learn_with_overlap` measures, how far each way it searches (px), the
#: normalised cross-correlation a tile's peak needs, and the grey std a tile needs in both drawings.
FIT_TILE_PX = 16
SEARCH_PX = 6
NCC_MIN = 0.6
TILE_STD = 6.0
#: The smaller eigenvalue of a tile's structure tensor (its grey gradients' second moments) over the larger that a
#: tile needs to be measured by cross-correlation: below it the tile holds an edge alone, along which the
#: correlation's peak slides (the aperture problem). Measured on rigs of the true lenses (six rendered frames of a
#: room, three of a photograph; ``bench/bench_overlap_tiles.py``): without it the tiles lay p90 2.19 / 0.14 px apart
#: (up to 6.4 px), with it 0.12 / 0.10 px (max 0.40 / 0.41), 181 / 411 tiles kept of 2174 / 1998.
MIN_CORNERNESS = 0.2
#: The Gaussian blur (sigma, px) of both drawings before cross-correlation: a picture sampled without blur (aliased
#: edges, as a sharp sensor's) made the tiles of the true lenses lie p90 1.10 px apart on three rendered frames of
#: a room sampled once a pixel, 0.63 px after it; frames sampled 3 x 3 a pixel: 0.13 and 0.12 px, either way.
LAYER_BLUR_PX = 0.7
#: Fewer textured tiles than this: the overlap is not compared.
MIN_TILES = 40
#: Cross-validation: sectors round the ring; the centre's move is kept where the left-out tiles' p90 with it is at
#: most KEEP_RATIO of the turn alone's and KEEP_GAIN_PX less.
SECTORS = 8
KEEP_RATIO = 0.8
KEEP_GAIN_PX = 0.3
#: Robust weights: Cauchy at twice the robust sigma, at least this (px).
MIN_SIGMA_PX = 0.1
#: Iterations of the reweighted least squares.
IRLS_STEPS = 10


@dataclass(frozen=True)
class OverlapTiles:
    """The textured tiles of a pair's overlap: ``centres`` (n, 2) band px (x, y), ``shifts`` (n, 2) band px (where
    camera j's drawing shows what camera i's shows at the centre, less the centre), on ``band``."""

    i: int
    j: int
    band: Band
    centres: FloatArray
    shifts: FloatArray

    @property
    def count(self) -> int:
        return int(self.centres.shape[0])

    def distances_px(self) -> FloatArray:
        """Each tile's shift's length (n,), px."""
        return np.hypot(self.shifts[:, 0], self.shifts[:, 1])


def overlap_tiles(
    rig: CameraRig,
    pictures: Any,
    i: int = 0,
    j: int = 1,
    *,
    tile_px: int = 16,
    min_std: float = TILE_STD,
    search_px: int = 0,
) -> OverlapTiles:
    """The overlap of cameras i and j in every shot of ``pictures`` (as :func:`~panomap.rig.learn.learn_rotations`
    takes them), cut in ``tile_px`` square tiles every ``tile_px / 2``; each tile both cameras see whole (and, with
    ``search_px``, that far round it), with grey std at least ``min_std`` in both, is compared.

    ``search_px`` 0: by phase correlation (the tile's shift understated where it is over a px or two); otherwise by
    normalised cross-correlation within ``search_px`` each way, both drawings blurred by :data:`LAYER_BLUR_PX`, the
    peak's place to a fraction of a px by a parabola each way (:func:`_ncc_shift`; a tile whose peak is on the
    search's edge, or correlates under :data:`NCC_MIN`, is left out, and so is a tile of camera i's drawing
    textured one way only, :func:`cornerness` under :data:`MIN_CORNERNESS`). Empty where the cameras do not
    overlap."""
    band = band_of(rig, i, j, 0.0)
    if band is None:
        empty = np.zeros((0, 2))
        return OverlapTiles(i, j, Band(np.zeros(3), np.zeros(3), np.zeros(3), 0.0, 1, 1), empty, empty)
    theta, rho = azimuth_elevation(band.rays())
    window = cv2.createHanningWindow((tile_px, tile_px), cv2.CV_64F)
    r = search_px
    maps, seen = [], []
    for k in (i, j):
        map_uv = rig.tables[k].sample(theta.astype(np.float32), rho.astype(np.float32))
        ok = np.all(np.isfinite(map_uv), axis=-1)
        maps.append([np.where(ok, map_uv[..., c], -1e4).astype(np.float32) for c in (0, 1)])
        seen.append(ok)
    both = seen[0] & seen[1]
    centres, shifts = [], []
    for shot in _shots(rig, pictures):
        layers = [
            cv2.remap(shot[k], map_u, map_v, cv2.INTER_LINEAR).astype(np.float64)
            for k, (map_u, map_v) in zip((i, j), maps, strict=True)
        ]
        if r and LAYER_BLUR_PX > 0:
            layers = [np.asarray(cv2.GaussianBlur(layer, (0, 0), LAYER_BLUR_PX), np.float64) for layer in layers]
        for v in range(r, band.height - tile_px - r + 1, tile_px // 2):
            for u in range(r, band.width - tile_px - r + 1, tile_px // 2):
                cut = (slice(v, v + tile_px), slice(u, u + tile_px))
                around = (slice(v - r, v + tile_px + r), slice(u - r, u + tile_px + r))
                a, b = layers[0][cut], layers[1][cut]
                if not (both[around].all() and min(a.std(), b.std()) >= min_std):
                    continue
                if r and cornerness(a) < MIN_CORNERNESS:
                    continue
                found = cv2.phaseCorrelate(a, b, window)[0] if r == 0 else _ncc_shift(a, layers[1][around], r)
                if found is not None:
                    centres.append((u + (tile_px - 1) / 2, v + (tile_px - 1) / 2))
                    shifts.append(found)
    shape = (-1, 2)
    return OverlapTiles(i, j, band, np.asarray(centres, np.float64).reshape(shape), np.asarray(shifts).reshape(shape))


def cornerness(tile: FloatArray) -> float:
    """The smaller eigenvalue of ``tile``'s (t, t) structure tensor over the larger (0: an edge or flat; 1: as
    textured every way); 0 where it has no gradient."""
    gy, gx = np.gradient(tile)
    a, b, c = float((gx * gx).sum()), float((gx * gy).sum()), float((gy * gy).sum())
    half_trace = (a + c) / 2
    root = math.sqrt(max(half_trace**2 - (a * c - b * b), 0.0))
    larger = half_trace + root
    return (half_trace - root) / larger if larger > 0 else 0.0


def _ncc_shift(tile: FloatArray, around: FloatArray, search_px: int) -> tuple[float, float] | None:
    """Where ``tile`` (t, t) lies in ``around`` (t + 2 r, t + 2 r), less ``r`` (px, (x, y)): the peak of their
    normalised cross-correlation, refined by a parabola through it and its neighbours each way; None where the peak
    is on the edge or under :data:`NCC_MIN`."""
    score = cv2.matchTemplate(around.astype(np.float32), tile.astype(np.float32), cv2.TM_CCOEFF_NORMED)
    y, x = np.unravel_index(int(np.argmax(score)), score.shape)
    if not (0 < x < 2 * search_px and 0 < y < 2 * search_px) or score[y, x] < NCC_MIN:
        return None

    def vertex(left: float, centre: float, right: float) -> float:
        curve = left - 2 * centre + right
        return 0.5 * (left - right) / curve if curve < 0 else 0.0

    dx = vertex(float(score[y, x - 1]), float(score[y, x]), float(score[y, x + 1]))
    dy = vertex(float(score[y - 1, x]), float(score[y, x]), float(score[y + 1, x]))
    return float(x - search_px + dx), float(y - search_px + dy)


def tile_jacobians(table_j: PanoMappingTable, tiles: OverlapTiles) -> tuple[Any, Any]:
    """The tiles' shifts' Jacobians (module docstring): ``A`` (n, 2, 3) in camera j's turn ``w`` (rad) and ``B``
    (n, 2, 2) in its picture's move ``c`` (px); ``B`` NaN where camera j's map is singular or unseen."""
    band, xy = tiles.band, tiles.centres
    d = band.rays_at(xy)
    h = 0.5
    ex, ey = np.array([h, 0.0]), np.array([0.0, h])
    dx = (band.rays_at(xy + ex) - band.rays_at(xy - ex)) / (2 * h)
    dy = (band.rays_at(xy + ey) - band.rays_at(xy - ey)) / (2 * h)
    # The band's axes are orthogonal on the sphere: H's rows are each axis over its squared length.
    big_h = np.stack([dx / np.sum(dx * dx, axis=1)[:, None], dy / np.sum(dy * dy, axis=1)[:, None]], axis=1)
    a = np.einsum("nij,njk->nik", big_h, _skew_rows(d))

    def pixel(rays: FloatArray) -> FloatArray:
        return table_j.sample(*azimuth_elevation(rays)).astype(np.float64)  # the table takes world rays

    g = np.stack([(pixel(band.rays_at(xy + e)) - pixel(band.rays_at(xy - e))) / (2 * h) for e in (ex, ey)], axis=2)
    det = g[:, 0, 0] * g[:, 1, 1] - g[:, 0, 1] * g[:, 1, 0]
    ok = np.isfinite(det) & (np.abs(det) > 1e-6)
    b = np.full((len(xy), 2, 2), np.nan)
    b[ok] = np.linalg.inv(g[ok])
    return a, b


def robust_fit(design: FloatArray, shifts: FloatArray) -> tuple[FloatArray, FloatArray]:
    """The parameters ``p`` (k,) that best give ``shifts`` (n, 2) as ``design @ p`` (design (n, 2, k)), by
    iteratively reweighted least squares: Cauchy weights on each component at twice that component's robust sigma
    (at least :data:`MIN_SIGMA_PX`), so the across-band component, which near objects' parallax spreads, weighs as
    little as it is spread; and the residuals (n, 2), px.

    Raises PanomapError where the design does not fix the parameters (too few tiles, or all along one line)."""
    k = design.shape[2]
    rows, values = design.reshape(-1, k), shifts.reshape(-1)
    weights = np.ones(shifts.shape)
    params = np.zeros(k)
    for _ in range(IRLS_STEPS):
        w = weights.reshape(-1)
        normal = rows.T @ (rows * w[:, None])
        scale = np.sqrt(np.diag(normal))
        if not np.all(scale > 0) or np.linalg.cond(normal / np.outer(scale, scale)) > 1e10:
            raise PanomapError("the overlap's tiles do not fix the turn (and centre): too few, or along one line")
        params = np.asarray(np.linalg.solve(normal, rows.T @ (values * w)), dtype=np.float64)
        residual = shifts - design @ params
        sigma = np.maximum(mad_sigma(residual, axis=0), MIN_SIGMA_PX)
        weights = 1.0 / (1.0 + (residual / (2 * sigma)) ** 2) / sigma**2
    return params, shifts - design @ params


def sector_residuals(design: FloatArray, shifts: FloatArray, lon: FloatArray) -> FloatArray:
    """Each tile's residual (n, 2), px, predicted from the tiles of the other :data:`SECTORS` sectors of the
    ring (``lon`` (n,): each tile's longitude round it, rad): a left-out sector's tiles by the fit of the rest."""
    sector = np.floor(np.mod(lon, 2 * math.pi) / (2 * math.pi) * SECTORS).astype(int)
    out = np.full(shifts.shape, np.nan)
    for s in range(SECTORS):
        held = sector == s
        if held.any() and (~held).sum() >= MIN_TILES // 2:
            params, _ = robust_fit(design[~held], shifts[~held])
            out[held] = shifts[held] - design[held] @ params
    return out


def shifted_table(table: PanoMappingTable, shift_px: FloatArray) -> PanoMappingTable:
    """``table``'s camera with its picture moved by ``shift_px`` (2,) px: its centre (and every entry) moved so, as a
    decentering of its image terms moves every pixel (a fitted table's entries filled anew from the moved model, an
    imported one's moved as they are); the move is added to ``info["centre moved px"]``, so that turning the table
    keeps it (:func:`~panomap.rig.learn.turned_table` resamples the moved entries; an imported table turned through
    its calibration, :func:`panomap.interop.orient.orient_table`, adds the move again)."""
    du, dv = (float(x) for x in shift_px)
    model = replace(table.model, centre=(table.model.centre[0] + du, table.model.centre[1] + dv))
    before = table.info.get("centre moved px", (0.0, 0.0))
    info = {**table.info, "centre moved px": (float(before[0]) + du, float(before[1]) + dv)}
    if table.entries_from_model:
        turned = model.rotation is not None
        camera_range = table.camera_range
        entries = fill_entries(model, table.size, table.elevation_range, camera_range=camera_range if turned else None)
    else:
        entries = np.asarray(table.entries, np.float32) + np.array([du, dv], dtype=np.float32)
    return replace(table, entries=entries, model=model, info=info)


def learn_with_overlap(
    rig: CameraRig,
    pictures: Any,
    *,
    turn: Callable[[PanoMappingTable, FloatArray], PanoMappingTable] = turned_table,
    seed: int = 0,
) -> LearnedRig:
    """A two-camera rig's rotations learned from its features (:func:`~panomap.rig.learn.learn_rotations`), and
    camera 1's centre moved where its overlap's tiles say it must be, only where that predicts tiles it was not
    fitted on.

    The tiles' shifts along the ring (parallax-free: near objects' parallax is across it) are fitted by a roll of
    camera 1 alone, and by a roll and a move of its centre (module docstring); the ring's :data:`SECTORS` sectors,
    each left out in turn, say whether the centre predicts the left-out tiles clearly better (along-ring p90 at
    most :data:`KEEP_RATIO` of the roll alone's and :data:`KEEP_GAIN_PX` less). Only then is the move kept: camera
    1's table moved (:func:`shifted_table`) and the rotations learned anew from the features with it (once: the
    move hardly depends on the rotation, which moves the tiles across the ring; the tiles measured again say how
    much more they would ask, ``left_px``). Otherwise the answer is
    :func:`~panomap.rig.learn.learn_rotations`'s. Rigs of other than two cameras: its answer, ``overlap`` None.

    Raises
    ------
    PanomapError
        As :func:`~panomap.rig.learn.learn_rotations`, or where the tiles do not fix the move.
    """
    learned = learn_rotations(rig, pictures, turn=turn, seed=seed)
    if rig.count != 2:
        return learned
    first = overlap_tiles(learned.rig, pictures, tile_px=FIT_TILE_PX, search_px=SEARCH_PX)
    if first.count < MIN_TILES:
        return learned
    step, held_roll, held_centre = _centre_step(learned.rig, first)
    keep = held_centre <= KEEP_RATIO * held_roll and held_roll - held_centre >= KEEP_GAIN_PX
    fit = OverlapFit(rig.names[1], first.count, _p90(first), _p90(first), held_roll, held_centre,
                     (float(step[0]), float(step[1])), keep, math.nan)  # fmt: skip
    if not keep:
        return replace(learned, overlap=fit)
    start = replace(rig, tables=(rig.tables[0], shifted_table(rig.tables[1], step)))
    learned = learn_rotations(start, pictures, turn=turn, seed=seed)  # a turn keeps the move (shifted_table)
    tiles = overlap_tiles(learned.rig, pictures, tile_px=FIT_TILE_PX, search_px=SEARCH_PX)
    left, _, _ = _centre_step(learned.rig, tiles, validate=False)
    fit = replace(fit, tiles=tiles.count, p90_px=_p90(tiles), left_px=float(np.hypot(*left)))
    return replace(learned, overlap=fit)


def _centre_step(rig: CameraRig, tiles: OverlapTiles, *, validate: bool = True) -> tuple[FloatArray, float, float]:
    """Camera 1's centre's move (2,) px fitted to the tiles' along-ring shifts with a roll; and, with ``validate``,
    the left-out sectors' along-ring residual p90 (px) by a roll alone and by the roll and the move (else NaN)."""
    a, b = tile_jacobians(rig.tables[1], tiles)
    ok = np.all(np.isfinite(b), axis=(1, 2))
    roll = (a @ tiles.band.pole)[ok, :1, None]  # the along-ring shift per rad of roll about the band's pole
    both = np.concatenate([roll, b[ok, :1, :]], axis=2)
    along = tiles.shifts[ok, :1]
    params, _ = robust_fit(both, along)
    if not validate:
        return params[1:], math.nan, math.nan
    lon = 2 * math.pi * (tiles.centres[ok, 0] + 0.5) / tiles.band.width
    held = []
    for design in (roll, both):
        left_out = np.abs(sector_residuals(design, along, lon))
        left_out = left_out[np.isfinite(left_out)]
        held.append(float(np.percentile(left_out, 90)) if left_out.size else math.nan)
    return params[1:], held[0], held[1]


def _p90(tiles: OverlapTiles) -> float:
    values = tiles.distances_px()
    return float(np.percentile(values, 90)) if values.size else math.nan


__all__ = [
    "OverlapFit",
    "OverlapTiles",
    "learn_with_overlap",
    "overlap_tiles",
    "robust_fit",
    "sector_residuals",
    "shifted_table",
    "tile_jacobians",
]
