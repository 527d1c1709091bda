"""The orchestration: :func:`find_image_circles` (starts, rim, cut-off disc, ellipse) and its no-rim
diagnosis.
"""

from __future__ import annotations

import functools
import math
import threading
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from ... import inputs
from ...errors import PanomapError
from ...strips import Ahead
from .cutoff import _cutoff_circle, _disc_without_rim
from .evidence import _either_polarity
from .fitting import _ellipse
from .frame import _arcs, _cropping_edges, _fraction_in_frame
from .rim import _best_rim, _halfway_rim, _iterate_rim, _refine_rim, _soft_rim, _soft_start
from .sampling import _downscaled, to_grey
from .scales import coarser_rim
from .starts import (
    _coarse_circle,
    _concentric_centres,
    _concentric_circles,
    _level_circles,
    _outermost_edge_circle,
    _surround_floor,
    _voted_circles,
)
from .thresholds import (
    CONCENTRIC_SEEDS,
    DARK_CORNER_CONTRAST,
    DARK_CORNER_FRACTION,
    DARK_LEVEL,
    DARK_PERCENTILE,
    EXPOSED_LEVEL,
    EXPOSED_SMOOTHING_GAIN,
    EXPOSED_SMOOTHING_PX,
    MAX_EXPOSURE_GAIN,
    MIN_FEATURE_FRACTION,
    MIN_FEATURE_FRACTION_LAST,
    MIN_FEATURE_FRACTION_OUTSIDE,
    NARROW_REACH,
    NEAR_FRACTION,
    NEAR_PX,
    SAME_START_FRACTION,
    SOFT_RIM_RMS_PX,
    STRETCH_BLACK_LEVEL,
    STRETCH_LEAST_GAIN,
    WIDE_REACH,
)
from .types import ImageCircles, NoImageCircle, _Rim


def exposed(grey: NDArray[np.float32], smoothed: bool = False) -> NDArray[np.float32]:
    """A dark picture ((H, W) grey levels 0..255) brightened as a well-exposed one: where its ``DARK_PERCENTILE``
    lies under ``DARK_LEVEL``, every level times the gain that takes it to ``EXPOSED_LEVEL`` (at most
    ``MAX_EXPOSURE_GAIN``), clipped at 255. Others unchanged.

    The finder's thresholds are in grey levels (an edge's strength, a rim's step), set on pictures that use
    their range; a dark picture (a tracking camera's, a room at dusk, a vignetted rim a quarter as bright)
    steps across its rim by a few levels and fails them (re-projected photographs at a quarter of their
    brightness: 4 of 8 rims lost, ``bench/bench_scenes.py --only circles``). With ``smoothed``, where the gain
    exceeds ``EXPOSED_SMOOTHING_GAIN``, the picture is smoothed first by a Gaussian of ``EXPOSED_SMOOTHING_PX``
    times the square root of the gain over it (px): the gain brightens the noise too, and a dark rim's edge
    points, each ray's outermost clear drop, fell on its blips past the rim; where it does not, ``grey`` itself
    (the finder searches the smoothed picture only where no rim passed in the other: a rim in a dark square
    steps by so few levels that the smoothing lost one of two such renders).
    """
    level = float(
        np.percentile(grey[:: max(1, grey.shape[0] // 400), :: max(1, grey.shape[1] // 400)], DARK_PERCENTILE)
    )
    if level >= DARK_LEVEL or level <= 0:
        return grey
    gain = min(EXPOSED_LEVEL / level, MAX_EXPOSURE_GAIN)
    if smoothed and gain <= EXPOSED_SMOOTHING_GAIN:
        return grey
    if smoothed:
        # The picture's noise brightened with it: smoothed back, as a symmetric blur leaves a rim where it is.
        sigma_px = EXPOSED_SMOOTHING_PX * math.sqrt(gain / EXPOSED_SMOOTHING_GAIN)
        grey = np.asarray(cv2.GaussianBlur(grey, (0, 0), sigma_px), np.float32)
    return np.minimum(grey * np.float32(gain), np.float32(255.0))


def find_image_circles(image: NDArray[Any]) -> ImageCircles:
    """Find the image centre, the image circle and the cut-off disc of an omni-image.

    The image circle may be cut by any of the frame's edges (a 4:3 or 16:9 sensor
    under a round image): it is fitted to the arcs of its rim that are visible.

    Parameters
    ----------
    image : (H, W[, C]) ndarray
        8- or 16-bit omni-image, any channel count.

    Raises
    ------
    NoImageCircle
        When no rim is visible (a full-frame fisheye, an ordinary photo, a blank
        image); it carries the frame centre as a starting value.
    """
    raw = to_grey(inputs.image(image))
    grey = exposed(raw)
    height, width = grey.shape
    frame_centre = ((width - 1) / 2, (height - 1) / 2)
    if min(height, width) < 32:
        raise NoImageCircle(
            f"no image circle found: the image is too small ({width} x {height}) to find an image circle in",
            frame_centre,
        )
    small, factor = _downscaled(grey)
    reasons: list[str] = []
    best = _searches(grey, small, factor, reasons)
    if best is None:
        # A dark picture brightened: its noise was too; the search again with the noise smoothed back.
        smoothed = exposed(raw, smoothed=True)
        if smoothed is not raw:  # (brightened by more than EXPOSED_SMOOTHING_GAIN)
            best = _searches(smoothed, _downscaled(smoothed)[0], factor, reasons)
            grey = smoothed if best is not None else grey
    if best is None:
        raise _no_rim(grey, small, factor, reasons, frame_centre)
    if best.polarity:
        best = _halfway_rim(grey, best)
    outer = best.circle
    centre = outer.centre
    ellipse = _ellipse(best.points, outer)
    if ellipse is not None:
        centre = ellipse.centre
    cutoff = _cutoff_circle(grey, centre, outer.radius)
    return ImageCircles(
        centre=centre,
        outer=outer,
        cutoff=cutoff,
        ellipse=ellipse,
        cropped_by=_cropping_edges(outer.centre, outer.radius, (height, width)),
        rim_in_frame=_fraction_in_frame(outer.centre, outer.radius, (height, width)),
        rim_seen=outer.inliers / outer.rays,
        rim_polarity={1: "bright inside", -1: "dark inside"}.get(best.polarity) or _either_polarity(grey, outer),
        rim_arcs_deg=_arcs(best.points, outer),
    )


def _searches(grey: NDArray[Any], small: NDArray[Any], factor: int, reasons: list[str]) -> _Rim | None:
    """The rim of ``grey`` (H, W; ``small`` its downscaled copy, shrunk by ``factor``): :func:`_search`'s; where
    none passes, its search in the picture stretched over a dark surround's floor (:func:`above_floor`); then,
    where none passes or the rim is one of either polarity that only some rays show, a bright disc's rim in the
    picture shrunk by 1, 2 and 4 (:func:`coarser_rim`), taken where it holds the other (:func:`_encloses`).
    None where none passes; each failure's reason appended to ``reasons``."""
    best = _search(grey, small, factor, reasons)
    if best is None:
        # A rim of low contrast: against a dark (not black) surround, or a picture dark at its edge.
        stretched = above_floor(grey, _surround_floor(small))
        if stretched is not None:
            stretched_small, _ = _downscaled(stretched)
            best = _search(stretched, stretched_small, factor, reasons)
    if best is None or (best.polarity == 0 and not best.convincing):
        # A rim too soft for the search at full resolution: looked for where the shrunk picture makes it sharp.
        # Also past a rim of either polarity that only some rays show: the rim is the outermost circle, and a
        # bright disc's rim around it, stepping on more of its rays, is the lens's (the other a circle of its scene).
        disc = coarser_rim(grey, functools.partial(_bright_disc, reasons=reasons))
        if best is None or (disc is not None and (_encloses(disc, best) or _same_rim(best, disc))):
            best = disc
    return best


def _search(grey: NDArray[Any], small: NDArray[Any], factor: int, reasons: list[str]) -> _Rim | None:
    """The rim of the stages (:func:`_search_stages`): the outermost of either polarity, a soft rim re-measured,
    a soft start where none passes; None where none does."""
    best = _search_stages(grey, small, factor, reasons)
    if best is not None and best.polarity == 0:
        best = _outermost_either(grey, best)
    if best is None:
        best = _soft_start(grey, small, factor, reasons)
    elif best.polarity != 0 and best.circle.rms_px > SOFT_RIM_RMS_PX:
        best = _soft_rim(grey, best)
    return best


def _encloses(disc: _Rim, other: _Rim) -> bool:
    """Whether ``disc`` is a bright disc's rim (stepping across on MIN_STEPPING_FRACTION of its rays in the frame,
    as it passed) that shows on a larger share of its rays in the frame than ``other`` (a rim of either polarity:
    its rays with an edge or line) and whose circle holds ``other``'s, NEAR_PX or more inside it."""
    inner = math.dist(disc.circle.centre, other.circle.centre) + other.circle.radius
    shown = disc.stepping / max(disc.rays_in_frame, 1.0) > other.stepping / max(other.rays_in_frame, 1.0)
    return disc.polarity > 0 and shown and inner <= disc.circle.radius - NEAR_PX


def _same_rim(other: _Rim, disc: _Rim) -> bool:
    """Whether ``other`` (a rim of either polarity) is ``disc``'s rim again (a bright disc's rim that shows on a
    larger share of its rays in the frame, as :func:`_encloses` asks): their centres and radii together within
    NARROW_REACH of the disc's radius.

    A lens barrel's edge lit past a dim, soft rim (a robot's fisheye vignetted by 80%, in a dark square) is an edge
    on the arcs where it shows and the rim one on the others: the search of either polarity found that circle
    first, 4.9 px off (bench/bench_circles_unkind.py's robot 24), and the bright disc's rim about the same circle,
    which the half-level re-measure then takes off the ring (0.06 px off), was not taken, as it did not hold it."""
    apart = math.dist(disc.circle.centre, other.circle.centre) + abs(other.circle.radius - disc.circle.radius)
    shown = disc.stepping / max(disc.rays_in_frame, 1.0) > other.stepping / max(other.rays_in_frame, 1.0)
    return disc.polarity > 0 and shown and apart <= NARROW_REACH * disc.circle.radius


def _bright_disc(grey: NDArray[np.float32], max_rms_px: float, reasons: list[str]) -> _Rim | None:
    """A bright disc's rim in ``grey`` (H, W) whose edge points lie on a circle within ``max_rms_px`` RMS: the
    best ranked (:attr:`_Rim.rank`) of the rims from the coarse blob, the round level lines
    (:func:`_level_circles`) and the circle transform's bright-inside circles, in turn until one is convincing;
    then the same in the picture stretched over its surround's floor (:func:`above_floor`). None where none
    passes; each failure's reason appended to ``reasons``."""
    small, factor = _downscaled(grey)
    for picture in (grey, above_floor(grey, _surround_floor(small))):
        if picture is None:
            continue
        picture_small = small if picture is grey else _downscaled(picture)[0]
        best: _Rim | None = None
        tried: list[tuple[tuple[float, float], float]] = []
        for start in (_coarse_circle, _level_circles, functools.partial(_voted_circles, polarity=1)):
            try:
                candidates = start(picture_small, factor)
            except PanomapError:
                continue
            for centre, radius in candidates:
                near = max(2.0, SAME_START_FRACTION * radius)
                if any(math.dist(centre, c) < near and abs(radius - r) < near for c, r in tried):
                    continue
                tried.append((centre, radius))
                try:
                    rim = _refine_rim(picture, centre, radius, 1, (NARROW_REACH, WIDE_REACH))
                except PanomapError as exc:
                    reasons.append(exc.detail)
                    continue
                if rim.circle.rms_px <= max_rms_px and (best is None or rim.rank > best.rank):
                    best = rim
                if best is not None and best.convincing:
                    return best
        if best is not None:
            return best
    return None


def above_floor(grey: NDArray[np.float32], floor: float | None) -> NDArray[np.float32] | None:
    """A picture whose rim has little contrast, stretched over the range: ``floor`` (a dark surround's level, or
    0) taken off, then every level times the gain that takes its ``DARK_PERCENTILE`` to 255 (at most
    ``MAX_EXPOSURE_GAIN``), clipped to 0..255. None where that changes little (no floor and a gain under
    ``STRETCH_LEAST_GAIN``): the search would find what it found; None too where the frame has no black
    (its 2nd percentile over ``STRETCH_BLACK_LEVEL``: a full-frame fisheye whose corners are dim, not black).

    The finder's thresholds are grey levels (a rim steps by 8): a rim against a dark (not black) square steps
    down by the picture's level less the square's (10-15 levels, against the 30 of the square's edge), and a
    picture that darkens to near black before its rim (strong vignetting) by 10 or so. Where no rim passed,
    the search runs again on this picture: existing finds are unchanged.
    """
    sample = grey[:: max(1, grey.shape[0] // 400), :: max(1, grey.shape[1] // 400)]
    black, level = (float(value) for value in np.percentile(sample, (2, DARK_PERCENTILE)))
    base = 0.0 if floor is None else floor
    if black > STRETCH_BLACK_LEVEL or level - base <= 0:
        return None  # no black frame: a full-frame fisheye's dim corners are no rim's surround
    gain = min(255.0 / (level - base), MAX_EXPOSURE_GAIN)
    if floor is None and gain < STRETCH_LEAST_GAIN:
        return None
    return np.clip((grey - np.float32(base)) * np.float32(gain), np.float32(0.0), np.float32(255.0))


def _search_stages(grey: NDArray[Any], small: NDArray[Any], factor: int, reasons: list[str]) -> _Rim | None:
    """The best rim of the stages, in order (each stage's failures appended to ``reasons``); None if none
    passes."""
    best: _Rim | None = None
    # A bright disc in a dark border first (the blob, then the circle transform); a rim of
    # either polarity (a mirror in a bright housing: darker inside than out on some arcs, a
    # thin line on others) only when that fails; a rim darker inside than out, checked by
    # its step alone, last.
    # Each stage: its candidates, the rim's polarity, and how far (a fraction of the radius)
    # the rim is looked for around a candidate: the blob's start may be rough (dark scene
    # touching the rim); the circle transform's is good to a few px.
    # A rim of either polarity: the circle transform's centres seed the concentric search,
    # whose circles, outermost first, are tried; the first that passes ends that search. (The
    # circle transform's own radii, tried after it, found nothing more in the tests and on the
    # real sets, and cost a third of the time where no rim passes.)
    either: list[list[tuple[tuple[float, float], float]]] = []
    either_lock = threading.Lock()  # the two stages that use it may run at once

    def voted_either() -> list[tuple[tuple[float, float], float]]:
        with either_lock:
            if not either:
                either.append(_voted_circles(small, factor, polarity=0, count=6))
            return either[0]

    def concentric() -> list[tuple[tuple[float, float], float]]:
        return _concentric_circles(grey, [centre for centre, _ in voted_either()[:CONCENTRIC_SEEDS]])

    def concentric_searched() -> list[tuple[tuple[float, float], float]]:
        if not voted_either():
            return []
        centre, radius = voted_either()[0]
        searched = _concentric_circles(grey, _concentric_centres(grey, centre))
        return searched + _outermost_edge_circle(grey, centre, radius)

    stages = (
        (lambda: _coarse_circle(small, factor), 1, (NARROW_REACH, WIDE_REACH), False),
        (lambda: _voted_circles(small, factor, polarity=1), 1, (NARROW_REACH,), False),
        (concentric, 0, (NARROW_REACH,), True),
        (concentric_searched, 0, (NARROW_REACH,), True),
        (lambda: _voted_circles(small, factor, polarity=-1, count=6), -1, (NARROW_REACH, WIDE_REACH), False),
    )
    tried: list[tuple[int, tuple[float, float], float]] = []
    # Where no rim passes, every stage runs and every candidate is tried: the next stage's
    # candidates are found, and the next candidate tried, on another core meanwhile.
    with Ahead(lambda stage: stage[0](), stages) as generated:
        for number, (_, polarity, reaches, first) in enumerate(stages):
            if best is not None and (polarity != best.polarity or best.convincing or best.polarity == 0):
                break
            try:
                candidates = generated.result(number)
            except PanomapError as exc:
                reasons.append(exc.detail)
                continue
            best = _best_rim(grey, candidates, polarity, reaches, first, best, tried, reasons)
    return best


def _outermost_either(grey: NDArray[Any], best: _Rim) -> _Rim:
    """The outermost circle of either polarity that passes, from ``best`` outward."""
    while True:
        # A rim of either polarity is the outermost circle that passes: inside a mirror's rim
        # the scene (a ceiling's edge) may draw circles too; outside it, the housing is blurred.
        # Past a circle that passed, the rim may show on fewer rays (the housing as bright as
        # the mirror on some arcs): a circle about the same centre needs MIN_FEATURE_FRACTION_OUTSIDE.
        try:
            further = _iterate_rim(
                grey,
                best.circle.centre,
                best.circle.radius * (1 + WIDE_REACH),
                0,
                WIDE_REACH,
                beyond=best.circle.radius + NEAR_PX,
                least_features=MIN_FEATURE_FRACTION_OUTSIDE,
                least_smooth=MIN_FEATURE_FRACTION_LAST,
            )
        except PanomapError:
            break
        moved = math.dist(further.circle.centre, best.circle.centre)
        if further.stepping < MIN_FEATURE_FRACTION * further.rays_in_frame and moved > max(
            NEAR_PX, NEAR_FRACTION * best.circle.radius
        ):
            break
        best = further
    return best


def _no_rim(
    grey: NDArray[Any], small: NDArray[Any], factor: int, reasons: list[str], frame_centre: tuple[float, float]
) -> NoImageCircle:
    """The error where no rim passes, in one line (the search's first failure kept as its ``reason``), and the
    cut-off disc where one shows."""
    reason = next((r for r in reasons if "rim" in r), reasons[0] if reasons else "no rim")
    reason = reason.removeprefix("no image circle found: ")
    one_arc = next((r.removeprefix("no image circle found: ") for r in reasons if "a rim shows, but" in r), None)
    start = f"the frame centre ({frame_centre[0]:.1f}, {frame_centre[1]:.1f}) is only a start"
    if one_arc is not None:
        # A rim shows, on too short an arc: no full-frame fisheye, and no centre to stand behind.
        seen = "no image circle found: a rim shows, but on too short an arc to fix its centre"
        return NoImageCircle(f"{seen}; {start}", frame_centre, reason=one_arc, seen=seen)
    if _dark_corners(small):
        # A picture in a dark border whose rim no test passed (too dark, too soft, too noisy): no full-frame
        # fisheye (its corners show the scene) and no mirror image overfilling the frame.
        seen = ("no image circle found: the frame's corners are dark around a picture, but its rim is too soft or "
                "faint to fit")  # fmt: skip
        return NoImageCircle(f"{seen}; {start}", frame_centre, reason=reason, seen=seen)
    disc = _disc_without_rim(grey, small, factor)
    if disc is not None:
        seen = "no image circle found: no rim is visible, but a cut-off disc is (a mirror image overfilling the frame)"
        return NoImageCircle(
            f"{seen}: its centre ({disc.centre[0]:.1f}, {disc.centre[1]:.1f}) is only a start",
            frame_centre,
            cutoff=disc,
            reason=f"{reason}; the cut-off disc's radius {disc.radius:.1f} px",
            seen=seen,
        )
    seen = "no image circle found: no rim is visible (a full-frame fisheye, or not an omni-image)"
    return NoImageCircle(f"{seen}; {start}", frame_centre, reason=reason, seen=seen)


def _dark_corners(small: NDArray[Any]) -> bool:
    """Whether the four corners of ``small`` (the downscaled (H, W) picture: a patch DARK_CORNER_FRACTION of its
    short side a side each) lie at most STRETCH_BLACK_LEVEL grey levels (median), and its middle half at least
    DARK_CORNER_CONTRAST over the brightest of them: a round image's frame (its circle cut by the frame or
    not), not a full-frame fisheye's, whose corners are scene."""
    height, width = small.shape
    side = max(2, round(DARK_CORNER_FRACTION * min(height, width)))
    corners = (small[:side, :side], small[:side, -side:], small[-side:, :side], small[-side:, -side:])
    darkest = max(float(np.median(corner)) for corner in corners)
    middle = float(np.median(small[height // 4 : 3 * height // 4, width // 4 : 3 * width // 4]))
    return darkest <= STRETCH_BLACK_LEVEL and middle - darkest >= DARK_CORNER_CONTRAST
