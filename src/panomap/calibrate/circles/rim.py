"""The rim from a start: refined from its edge points, iterated about the new centre, scored, the best
candidate chosen; a soft rim re-measured.
"""

from __future__ import annotations

import functools
import math
from typing import Any

import cv2
from numpy.typing import NDArray

from ...errors import PanomapError
from ...strips import Ahead
from .evidence import _feature_points, _feature_rays, _rim_points, _smooth_beyond, _stepping_rays
from .fitting import _ellipse, _robust_circle, centre_uncertainty_px
from .frame import _fraction_in_frame, _least_rim_rays, _sectors_in_frame, _sectors_seen
from .starts import _coarse_circle
from .thresholds import (
    DARK_INSIDE_LEAST_IN_FRAME,
    EARLY_STEPPING_SHARE,
    HALFWAY_GAIN,
    HALFWAY_ITERATIONS,
    HALFWAY_LEAST_SHARE,
    HALFWAY_MORE,
    MAX_CENTRE_UNCERTAINTY_PX,
    MAX_RIM_RMS_PX,
    MIN_FEATURE_FRACTION,
    MIN_FEATURE_FRACTION_OUTSIDE,
    MIN_RIM_SECTORS,
    MIN_RIM_SECTORS_EITHER,
    MIN_STEPPING_FRACTION,
    MIN_STEPPING_FRACTION_DARK_INSIDE,
    NARROW_REACH,
    RAYS,
    SAME_START_FRACTION,
    SOFT_RIM_GAIN,
    SOFT_RIM_SIGMAS_PX,
    WIDE_REACH,
)
from .types import Circle, ShortArc, _Rim


def _soft_rim(grey: NDArray[Any], rim: _Rim) -> _Rim:
    """``rim`` fitted again on the image smoothed by each of SOFT_RIM_SIGMAS_PX, where that fits clearly better."""
    best = rim
    for sigma in SOFT_RIM_SIGMAS_PX:
        smooth = cv2.GaussianBlur(grey, (0, 0), sigma)
        try:
            found = _iterate_rim(smooth, rim.circle.centre, rim.circle.radius, rim.polarity, NARROW_REACH)
        except PanomapError:
            continue
        same = 2 * rim.circle.rms_px
        if (
            found.circle.rms_px < SOFT_RIM_GAIN * best.circle.rms_px
            and abs(found.circle.radius - rim.circle.radius) <= same
            and math.dist(found.circle.centre, rim.circle.centre) <= same
        ):
            best = found
    return best


def _halfway_rim(grey: NDArray[Any], rim: _Rim) -> _Rim:
    """A bright- or dark-inside ``rim`` whose edge points are measured again at each ray's half level
    (:func:`_rim_points` with ``halfway``) and fitted again about its circle, up to HALFWAY_ITERATIONS times (until
    it moves by under 0.01 px); kept where its points lie on it clearly better (:func:`_fits_better`). ``rim``
    itself where that fails, finds fewer than HALFWAY_LEAST_SHARE of its inliers, fits no better, or moves the
    circle (centre and radius together) by the search's reach or more: another edge than the one the search chose.

    The search ranks candidates by each ray's outermost clear drop; once it has chosen the rim, the half level is
    the better measure of where that drop lies: a lit barrel's ring or a glow on the rim's outer slope moves the
    steepest point out on the arcs where it shows, not the half level (bench/bench_circles_unkind.py).
    """
    centre, radius = rim.circle.centre, rim.circle.radius
    for _ in range(HALFWAY_ITERATIONS):
        points = _rim_points(grey, centre, radius, rim.polarity, NARROW_REACH, halfway=True)
        if len(points) < HALFWAY_LEAST_SHARE * rim.circle.inliers:
            return rim
        try:
            circle = _robust_circle(points, centre, radius, consensus=False)
        except PanomapError:
            return rim
        step = math.dist(circle.centre, centre) + abs(circle.radius - radius)
        centre, radius = circle.centre, circle.radius
        if step < 0.01:
            break
    moved = math.dist(circle.centre, rim.circle.centre) + abs(circle.radius - rim.circle.radius)
    if (
        moved >= NARROW_REACH * rim.circle.radius
        or circle.inliers < HALFWAY_LEAST_SHARE * rim.circle.inliers
        or not _fits_better(circle, rim.circle)
    ):
        return rim
    return _Rim(circle, points, rim.rays_in_frame, rim.polarity, rim.stepping)


def _fits_better(circle: Circle, other: Circle) -> bool:
    """Whether ``circle``'s edge points lie on it clearly better than ``other``'s on it: an RMS under HALFWAY_GAIN of
    the other's, or HALFWAY_MORE times its inliers at an RMS under the other's over HALFWAY_GAIN."""
    if circle.rms_px <= HALFWAY_GAIN * other.rms_px:
        return True
    return circle.inliers >= HALFWAY_MORE * other.inliers and circle.rms_px * HALFWAY_GAIN <= other.rms_px


def _soft_start(grey: NDArray[Any], small: NDArray[Any], factor: int, reasons: list[str]) -> _Rim | None:
    """Where no rim passed: a bright disc's rim looked for again on the image smoothed by the widest of
    SOFT_RIM_SIGMAS_PX (a rim too soft for its edge points to lie on a circle at full sharpness); None if none."""
    try:
        candidates = _coarse_circle(small, factor)
    except PanomapError:
        return None
    smooth = cv2.GaussianBlur(grey, (0, 0), SOFT_RIM_SIGMAS_PX[-1])
    return _best_rim(smooth, candidates, 1, (NARROW_REACH, WIDE_REACH), False, None, [], reasons)


def _best_rim(
    grey: NDArray[Any],
    candidates: list[tuple[tuple[float, float], float]],
    polarity: int,
    reaches: tuple[float, ...],
    first: bool,
    best: _Rim | None,
    tried: list[tuple[int, tuple[float, float], float]],
    reasons: list[str],
) -> _Rim | None:
    """The best of ``best`` and the rims refined from a stage's ``candidates`` (start centre, radius), in order.

    A candidate is skipped where it is ``best``'s circle again or starts where one in
    ``tried`` (appended to) did at this polarity. Tried in turn until one is convincing
    (or, with ``first``, passes); each failure's reason is appended to ``reasons``.
    """
    refine = functools.partial(_refine_start, grey, polarity, reaches, first)
    with Ahead(refine, candidates) as refined:
        for index, (centre, radius) in enumerate(candidates):
            if best is not None and math.dist(centre, best.circle.centre) < 2 and abs(radius - best.circle.radius) < 2:
                continue  # the same circle again
            # A start this close to one already tried at this polarity ends where that one did.
            near = max(2.0, SAME_START_FRACTION * radius)
            if any(p == polarity and math.dist(centre, c) < near and abs(radius - r) < near for p, c, r in tried):
                continue
            tried.append((polarity, centre, radius))
            try:
                found = refined.result(index)
            except PanomapError as exc:
                reasons.append(exc.detail)
                continue
            if best is None or found.rank > best.rank:
                best = found
            if best.convincing or first:
                break
    return best


def _refine_start(
    grey: NDArray[Any], polarity: int, reaches: tuple[float, ...], first: bool, start: tuple[tuple[float, float], float]
) -> _Rim:
    """:func:`_refine_rim` from ``start`` (centre, radius): ``first`` passes a polarity-0 rim on its last edge."""
    return _refine_rim(grey, start[0], start[1], polarity, reaches, last_edge=first)


def _refine_rim(
    grey: NDArray[Any],
    centre: tuple[float, float],
    radius: float,
    polarity: int,
    reaches: tuple[float, ...],
    last_edge: bool = False,
) -> _Rim:
    """Rim edge points and the robust circle through them, iterated from a start circle.

    The rim is first looked for within ``reaches[0]`` of the start radius (a good start:
    the scene further in is then no distraction), then within each next reach. With
    ``last_edge`` (polarity 0), a circle with an edge on MIN_FEATURE_FRACTION_OUTSIDE of the
    rays, in MIN_RIM_SECTORS sectors, passes where the image past it is smooth (:func:`_smooth_beyond`).
    """
    failure = PanomapError("no image circle found")
    for reach in reaches:
        try:
            if last_edge:
                return _iterate_rim(grey, centre, radius, polarity, reach, least_smooth=MIN_FEATURE_FRACTION_OUTSIDE)
            return _iterate_rim(grey, centre, radius, polarity, reach)
        except PanomapError as exc:
            if not isinstance(failure, ShortArc):  # (a rim seen, on one arc, is what to say)
                failure = exc
    raise failure


def _iterate_rim(
    grey: NDArray[Any],
    centre: tuple[float, float],
    radius: float,
    polarity: int,
    reach: float,
    beyond: float = 0.0,
    least_features: float = MIN_FEATURE_FRACTION,
    least_smooth: float | None = None,
) -> _Rim:
    """:func:`_refine_rim` with the first search ``reach`` times the radius wide (polarity 0: past ``beyond``,
    with an edge or line on ``least_features`` of the rays in the frame, in MIN_RIM_SECTORS_EITHER sectors;
    or, given ``least_smooth``, on that fraction in MIN_RIM_SECTORS sectors where the image past the
    circle is smooth: the last edge, a rim seen only on some arcs)."""
    height, width = grey.shape
    circle = None
    for iteration in range(4):
        if polarity:
            points = _rim_points(grey, centre, radius, polarity, reach if iteration == 0 else NARROW_REACH)
        else:
            first = iteration == 0
            points = _feature_points(
                grey, centre, radius, reach if first else NARROW_REACH, not first, beyond if first else 0.0
            )
        if len(points) < _least_rim_rays(centre, radius, (height, width), polarity):
            kind = {1: "bright-to-dark", -1: "dark-to-bright", 0: "clear"}[polarity]
            raise PanomapError(f"no image circle found: only {len(points)} of {RAYS} rays cross a {kind} rim")
        circle = _robust_circle(points, centre, radius, consensus=iteration == 0)
        if circle.inliers < _least_rim_rays(circle.centre, circle.radius, (height, width), polarity):
            break  # no rim here: rejected below, without iterating
        if iteration == 0 and polarity:
            # The first circle already lies within a few px of a rim there is: where the levels
            # step across it on under half the rays the final test asks for, there is none.
            in_frame = _fraction_in_frame(circle.centre, circle.radius, (height, width)) * RAYS
            least = MIN_STEPPING_FRACTION if polarity > 0 else MIN_STEPPING_FRACTION_DARK_INSIDE
            stepping = _stepping_rays(grey, circle, polarity)
            if stepping < EARLY_STEPPING_SHARE * least * in_frame:
                raise PanomapError(
                    f"no image circle found: the levels inside and outside the first circle differ on only "
                    f"{stepping} of the {in_frame:.0f} rays in the frame"
                )
        moved = math.dist(circle.centre, centre) + abs(circle.radius - radius)
        centre, radius = circle.centre, circle.radius
        if not (0 <= centre[0] < width and 0 <= centre[1] < height) or radius < 0.2 * min(height, width):
            raise PanomapError("no image circle found: the only circle is too small or off the image")
        if moved < 0.01:
            break
    assert circle is not None
    in_frame = _fraction_in_frame(circle.centre, circle.radius, (height, width)) * RAYS
    sectors = _sectors_seen(points, circle)
    # Of the sectors the frame shows: a circle cut by all four edges (a round image larger than a
    # square frame) shows four arcs about the corners, in as few as 4 of the 12 sectors.
    shown = _sectors_in_frame(circle, (height, width))
    least_sectors = math.ceil(
        (MIN_RIM_SECTORS if polarity or least_smooth is not None else MIN_RIM_SECTORS_EITHER) * shown / 12
    )
    if (
        circle.inliers < _least_rim_rays(circle.centre, circle.radius, (height, width), polarity)
        or sectors < least_sectors
        or (circle.rms_px > MAX_RIM_RMS_PX and _ellipse(points, circle) is None)
    ):
        raise PanomapError(
            f"no image circle found: the rim's edge points do not lie on a circle "
            f"({circle.inliers} of {RAYS} agree, in {sectors} of 12 sectors, RMS {circle.rms_px:.2f} px)"
        )
    if polarity < 0 and in_frame < DARK_INSIDE_LEAST_IN_FRAME * RAYS:
        raise PanomapError(
            f"no image circle found: the frame shows only {in_frame / RAYS:.0%} of the circle darker inside than "
            f"out (a mirror's housing frames it)"
        )
    if polarity:
        stepping = _stepping_rays(grey, circle, polarity)
        least = MIN_STEPPING_FRACTION if polarity > 0 else MIN_STEPPING_FRACTION_DARK_INSIDE
        if stepping < least * in_frame:
            raise PanomapError(
                f"no image circle found: the levels inside and outside the best circle differ on only "
                f"{stepping} of the {in_frame:.0f} rays in the frame"
            )
    else:
        stepping = _feature_rays(grey, circle)
        outright = stepping >= least_features * in_frame and sectors >= math.ceil(MIN_RIM_SECTORS_EITHER * shown / 12)
        if not outright and (
            least_smooth is None or stepping < least_smooth * in_frame or not _smooth_beyond(grey, circle)
        ):
            raise PanomapError(
                f"no image circle found: an edge or a line stands out on the best circle on only "
                f"{stepping} of the {in_frame:.0f} rays in the frame"
            )
    uncertainty = centre_uncertainty_px(points, circle)
    if uncertainty > MAX_CENTRE_UNCERTAINTY_PX:
        # A bright disc's rim (a lens's image circle against its dark surround) shows, on too short an arc; a
        # circle of another kind there may as well be the scene's.
        detail = (
            f"({circle.inliers} rays, {circle.rms_px:.1f} px RMS) that it does not fix its centre "
            f"(to {uncertainty:.1f} px)"
        )
        if polarity > 0:
            raise ShortArc(f"no image circle found: a rim shows, but on so short an arc {detail}")
        raise PanomapError(f"no image circle found: the circle's points lie on so short an arc {detail}")
    return _Rim(circle, points, in_frame, polarity, stepping)
