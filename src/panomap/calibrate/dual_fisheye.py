"""A dual fisheye learned from its own frames, no calibration: each lens from its lines, then the turn between them.

Convention (docs/conventions.md, "A rig"): a frame holds the two lenses side by side, lens 0 in the left half; lens 0
places the world (it looks along yaw 0, pitch 0; its azimuth origin is the image's +u, as a line fit's is), lens 1
starts looking the other way (yaw 180 deg) and is turned by :func:`panomap.rig.learn.learn_rotations`. Pixels (u, v)
with the top-left pixel's centre at (0, 0), each in its own half; bands and residuals in px, angles in deg.

What one dual-fisheye picture pins, and what it does not (:mod:`panomap.calibrate.lines.stretch`):

- each lens's centre and radial law from its straight lines, **but for a stretch along its axis**: a lens stretched
  along its axis (each ray ``d`` seen as ``S d / |S d|``, ``S = diag(1, 1, s)``) keeps every line straight, so only
  the scene's right angles oblique to the axis pin ``s`` (each lens's fit measures the range they leave, in its band);
- the overlap (the ring 85-95 deg off both axes) pins the **turn** between the lenses and their **relative** stretch
  (two lenses stretched by different ``s`` disagree there: a ray at ``alpha`` off the axis moves by about
  ``(s - 1) sin(alpha) cos(alpha)`` rad, 0.05-0.1 deg per 1% at the rim);
- it never pins the **common** stretch: both lenses stretched by one ``s`` along their shared axis is one linear map
  of the world, under which the overlap's matches agree and every line stays straight.

So the rig is written only where both lenses are pinned by their own pictures (each lens's 95% band within the line
fit's limits, :mod:`panomap.calibrate.lines.agreement`) and they draw their overlap alike within their bands;
otherwise it is refused in one line (what to do: a checkerboard picture of each lens, or their calibration), the
figures after it.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import PanomapError, refusal
from ..geometry import FloatArray
from ..interop.orient import orient_table, turn_table
from ..rig.learn import LearnedRig, learn_rotations
from ..rig.overlap import SEARCH_PX, overlap_tiles
from ..rig.rig import CameraRig
from ..table.table import PanoMappingTable
from .lines.agreement import RING_TO_DEG, Z95
from .pictures import LearnedCalibration, learn_from_images

#: The names of the two lenses, left half first.
LENS_NAMES = ("lens0", "lens1")
#: The overlap's tiles (:func:`overlap_shifts_px`) may lie this far apart (px, p90) beyond the two lenses' bands at
#: the rim added. Measured by normalised cross-correlation on tiles textured both ways, with rigs of the true lenses
#: turned as their features say (``bench/bench_overlap_tiles.py``: six rendered frames of a room; three of a real
#: photograph): p90 0.12 / 0.10 px where the lenses agree; lens 1's law scaled by 1.005 / 1.01: 1.92 / 4.12 px
#: (room), 1.83 / 2.80 px (photograph); its centre 8 px off: 3.43 / 4.20 px. (Phase correlation, used before, read
#: these 0.66 / 1.00 and 1.02 px on the room: it understates shifts over a px, and neither the 1% scale nor the 8 px
#: let the check refuse.) Fewer than ``MIN_TILES`` tiles cannot check.
TILE_NOISE_PX = 0.5
MIN_TILES = 20
#: The overlap's tiles (px, square) compared between the two lenses, and the grey levels' spread (std) a tile
#: needs in both to be compared.
TILE_PX = 16
TILE_STD = 6.0
#: What a user does where a dual fisheye cannot be learned from its frames (each refusal's end; the figures add
#: the other way: the lenses' calibration, panomap import).
REMEDY = "fit each lens to a checkerboard (panomap fit --image), then rig learn RIG FRAME"
OTHER_WAY = (
    "what to do: a checkerboard held tilted 30-60 deg in a few pictures of each lens (panomap fit --image), or the "
    "lenses' calibration (panomap import, --side-by-side), makes each lens's table; panomap rig make --side-by-side "
    "puts them in a rig and panomap rig learn RIG FRAME learns the turn between them from the overlap"
)


@dataclass(frozen=True)
class LensBand:
    """How well one lens is pinned by its pictures: its 95% band (px) at 90% of the rings 15-85 deg off its axis
    and at all of them (``p90_px``, ``max_px``), at the overlap's rings beyond 85 deg (``rim_px``, NaN where the fit
    reaches none), and what widens it most (``farthest``: another camera the lines allow, such as the lens
    stretched along its axis as far as its right angles leave it)."""

    p90_px: float
    max_px: float
    rim_px: float
    farthest: str

    def describe(self) -> str:
        rim = f", {self.rim_px:.2f} px beyond 85 deg" if math.isfinite(self.rim_px) else ""
        return (
            f"95% band {self.p90_px:.2f} px at 90% of the rings 15-85 deg, {self.max_px:.2f} px at most{rim} "
            f"(widest for {self.farthest})"
        )


@dataclass(frozen=True)
class DualFisheye:
    """A dual fisheye learned from its frames (:func:`learn_dual_fisheye`).

    ``rig``: the two lenses' tables, side by side, lens 1 turned as the overlap says; ``lenses``: each lens's
    :class:`~panomap.calibrate.pictures.LearnedCalibration`; ``bands``: each lens's :class:`LensBand`;
    ``learned``: the rotation's :class:`~panomap.rig.learn.LearnedRig` (its pair report: the overlap's residual);
    ``overlap_shifts_px``: (n,) how far apart the two lenses draw each textured tile of their overlap
    (:func:`overlap_shifts_px`); ``overlap_limit_px``: what their p90 was allowed.
    """

    rig: CameraRig
    lenses: tuple[LearnedCalibration, LearnedCalibration]
    bands: tuple[LensBand, LensBand]
    learned: LearnedRig
    overlap_shifts_px: FloatArray
    overlap_limit_px: float

    def describe(self) -> list[str]:
        lines = []
        for name, lens, band in zip(self.rig.names, self.lenses, self.bands, strict=True):
            lines.append(
                f"{name}: learned from its {lens.source} ({len(lens.fit.report.lines)} lines); {band.describe()}"
            )
        pair = self.learned.pairs[0]
        lines.append(
            f"the overlap: {_shifts(self.overlap_shifts_px)} (p90 allowed {self.overlap_limit_px:.2f}); its features: "
            f"{pair.describe()}; it pins the turn between "
            f"the lenses (uncertainty {self.learned.uncertainty_deg[1]:.4f} deg) and their relative stretch, not the "
            "stretch common to both along their axis: each lens's right angles pin that, within its band"
        )
        return lines


def split_frame(frame: NDArray[Any]) -> tuple[NDArray[Any], NDArray[Any]]:
    """The two halves (H, W/2[, C]) of a side-by-side frame (H, W[, C]): lens 0 (left), lens 1 (right).

    Raises PanomapError where the frame's width is odd (no two halves of one size)."""
    width = frame.shape[1]
    if width % 2:
        raise PanomapError(f"a side-by-side frame {width} px wide: two lenses of one size make it even")
    half = width // 2
    return np.ascontiguousarray(frame[:, :half]), np.ascontiguousarray(frame[:, half:])


def lens_band(learned: LearnedCalibration) -> LensBand:
    """The lens's 95% band (px) from its line fit's rings (:class:`LensBand`); NaN where the fit has none."""
    fit = learned.fit
    if fit.band is None:
        projection = fit.report.projection
        if projection is None:
            return LensBand(math.nan, math.nan, math.nan, "nothing: the fit states no band")
        rings = np.asarray(projection.ring_band_px, dtype=np.float64)
        alpha = np.asarray(projection.alpha_deg, dtype=np.float64)
        inner, outer = rings[alpha <= RING_TO_DEG + 1e-9], rings[alpha > RING_TO_DEG + 1e-9]
        return LensBand(
            float(np.percentile(inner, 90)) if inner.size else math.nan,
            float(np.max(inner)) if inner.size else math.nan,
            float(np.max(outer)) if outer.size else math.nan,
            "the checkerboards' corners' noise",
        )
    band = Z95 * fit.band.se_px(fit.jacobian_se_px())
    alpha = fit.band.alpha_deg
    judged = band[alpha <= RING_TO_DEG + 1e-9]
    rim = band[alpha > RING_TO_DEG + 1e-9]
    return LensBand(
        float(np.percentile(judged, 90)) if judged.size else math.nan,
        float(np.max(judged)) if judged.size else math.nan,
        float(np.max(rim)) if rim.size else math.nan,
        fit.band.farthest,
    )


def learn_dual_fisheye(
    frames: Sequence[NDArray[Any]] | NDArray[Any],
    *,
    seed: int = 0,
    progress: Callable[[str], None] | None = None,
) -> DualFisheye:
    """A dual fisheye learned from its own side-by-side frames, no calibration: each lens from its lines (all its
    halves together, :func:`panomap.calibrate.pictures.learn_from_images`), then the turn between them from their
    overlap (:func:`panomap.rig.learn.learn_rotations`), the two lenses' drawings of the overlap checked against their
    bands (:func:`pair_lenses`).

    Parameters
    ----------
    frames : (H, W[, C]) ndarray, or a sequence of them
        Frames of one dual fisheye (lens 0 in the left half), all of one size; more frames (turned, moved) give
        more lines.
    seed : int
        The rotation's RANSAC seed.
    progress : callable, optional
        ``progress(what)`` before each step.

    Returns
    -------
    DualFisheye

    Raises
    ------
    PanomapError
        Where a lens, or the pair, cannot be pinned: the first line says which and what to do (:data:`REMEDY`),
        the lines after it the figures (the lens's own refusal; the overlap's residual against the bands).
    """
    say = progress or (lambda _what: None)
    shots = [np.asarray(frames)] if isinstance(frames, np.ndarray) else [np.asarray(f) for f in frames]
    if not shots:
        raise PanomapError("no frame to learn the dual fisheye from")
    halves = [split_frame(frame) for frame in shots]
    lenses = _learn_lenses([[h[k] for h in halves] for k in (0, 1)], say)
    say("learning the turn between the lenses from their overlap")
    return pair_lenses(lenses, shots, seed=seed)


def pair_lenses(
    lenses: tuple[LearnedCalibration, LearnedCalibration], frames: Sequence[NDArray[Any]], *, seed: int = 0
) -> DualFisheye:
    """Two lenses learned each on its own, put back to back and turned as their overlap in ``frames`` (side by
    side, lens 0 on the left) says; refused where the overlap does not place them, or where the two lenses' drawings
    of it lie apart (p90 of its tiles' shifts, :func:`overlap_shifts_px`) by more than the two lenses' bands at the
    rim added, plus :data:`TILE_NOISE_PX`.

    Raises
    ------
    PanomapError
        One line (what to do: :data:`REMEDY`), the figures after it.
    """
    bands = (lens_band(lenses[0]), lens_band(lenses[1]))
    for k, band in enumerate(bands):
        if not math.isfinite(band.max_px):  # (a rim without rings falls back on max_px: _overlap_limit)
            raise PanomapError(
                refusal(f"lens {k}'s fit states no band to check it by: {REMEDY}", f"{_what_it_pins()}\n{OTHER_WAY}")
            )
    rig = _start_rig(lenses[0].table, lenses[1].table)
    try:
        learned = learn_rotations(rig, list(frames), turn=turn_table, seed=seed)
    except PanomapError as exc:
        raise PanomapError(
            refusal(
                f"the overlap does not place the lenses: {REMEDY}",
                f"{exc.summary}\n{_what_it_pins()}\n{OTHER_WAY}",
            )
        ) from None
    limit = _overlap_limit(bands)
    shifts = overlap_shifts_px(learned.rig, frames)
    shift = float(np.percentile(shifts, 90)) if shifts.size >= MIN_TILES else math.nan
    if not shift <= limit:
        said = f"overlap off by {shift:.1f} px ({limit:.1f} allowed)" if shifts.size >= MIN_TILES else (
            f"the overlap shows too little texture to check the lenses ({shifts.size} tiles)")  # fmt: skip
        raise PanomapError(
            refusal(
                f"{said}: {REMEDY}",
                f"the overlap: {_shifts(shifts)}; its features: {learned.pairs[0].describe()}\nlens 0: "
                f"{bands[0].describe()}\nlens 1: {bands[1].describe()}\nallowed: the two bands beyond 85 deg added, "
                f"plus {TILE_NOISE_PX} px of the tiles' own spread, at {MIN_TILES} tiles or more\n{_what_it_pins()}\n"
                f"{OTHER_WAY}",
            )
        )
    info = {**learned.rig.info, "learned from": "its own frames (panomap rig learn --side-by-side)"}
    out = CameraRig(learned.rig.tables, learned.rig.names, learned.rig.offsets, info)
    return DualFisheye(out, lenses, bands, learned, shifts, limit)


def _shifts(shifts: FloatArray) -> str:
    """The overlap's tile shifts in words."""
    if not shifts.size:
        return "no tile textured in both lenses"
    p50, p90, top = np.percentile(shifts, [50, 90, 100])
    return f"{shifts.size} tiles, the lenses' drawings {p50:.2f} / {p90:.2f} / {top:.2f} px apart (p50 / p90 / max)"


def overlap_shifts_px(rig: CameraRig, frames: Sequence[NDArray[Any]]) -> FloatArray:
    """How far apart the two lenses put the same scene in their overlap (px): the overlap's band (the ring of
    directions seen by both, :func:`panomap.rig.learn.band_of`, no margin) drawn from each lens's half through its
    table, cut in :data:`TILE_PX` square tiles; each tile both lenses see whole, and textured in both (grey std at
    least :data:`TILE_STD`, and both ways: :data:`panomap.rig.overlap.MIN_CORNERNESS`), gives the shift between the
    two lenses' drawings by normalised cross-correlation within :data:`panomap.rig.overlap.SEARCH_PX` each way
    (:func:`panomap.rig.overlap.overlap_tiles`; px at the band's scale, the lenses' finest there: about the
    pictures' own px). Every frame's tiles, (n,); empty where none."""
    return overlap_tiles(rig, list(frames), tile_px=TILE_PX, min_std=TILE_STD, search_px=SEARCH_PX).distances_px()


def _learn_lenses(
    pictures: list[list[NDArray[Any]]], say: Callable[[str], None]
) -> tuple[LearnedCalibration, LearnedCalibration]:
    """Each lens from its halves (``pictures[k]``); where either is not pinned, one refusal naming them (each
    lens's own refusal in the figures)."""
    learned: list[LearnedCalibration] = []
    refused: list[str] = []
    for k, side in enumerate(("left", "right")):
        say(f"learning lens {k} (the {side} half) from its lines")
        try:
            learned.append(learn_from_images(pictures[k], boards=True))
        except PanomapError as exc:
            refused.append(f"lens {k} ({side}): {exc.detail}")
    if refused:
        who = "lens 0 (left) is" if refused[0].startswith("lens 0") else "lens 1 (right) is"
        raise PanomapError(
            refusal(
                f"{'neither lens is' if len(refused) == 2 else who + ' not'} pinned by these frames: {REMEDY}",
                "\n".join([*refused, _what_it_pins(), OTHER_WAY]),
            )
        )
    return learned[0], learned[1]


def _what_it_pins() -> str:
    return (
        "what one dual-fisheye picture pins: each lens's centre and law from its straight lines but for a stretch "
        "along its axis (lines stay straight under it; only right angles oblique to the axis measure it), and from "
        "the overlap the turn between the lenses and their relative stretch; never the stretch common to both lenses "
        "along their axis (one linear map of the world, under which the overlap agrees and every line stays straight)"
    )


def _overlap_limit(bands: tuple[LensBand, LensBand]) -> float:
    """The overlap's tile shifts' p90 allowed (px): the two lenses' bands at the rim (their largest band where no ring
    reaches it) added, plus :data:`TILE_NOISE_PX`."""
    total = 0.0
    for band in bands:
        total += band.rim_px if math.isfinite(band.rim_px) else band.max_px
    return total + TILE_NOISE_PX


def _start_rig(table0: PanoMappingTable, table1: PanoMappingTable) -> CameraRig:
    """The two lenses back to back: lens 0 looking along yaw 0, lens 1 along yaw 180 deg (both level), side by side."""
    turned = (orient_table(table0, 0.0, 0.0, 0.0), orient_table(table1, math.pi, 0.0, 0.0))
    width = table0.image_size[0]  # type: ignore[index]
    return CameraRig(turned, LENS_NAMES, ((0, 0), (width, 0)), {"lenses": "learned from their lines"})


__all__ = ["DualFisheye", "LensBand", "learn_dual_fisheye", "lens_band", "pair_lenses", "split_frame"]
