"""Finding the image centre, the cut-off radius and the image circle in an omni-image.

Convention: pixel (u, v), u the column, v the row, the centre of the top-left
pixel at (0, 0); radii in px; image angle ``atan2(v - v0, u - u0)``.

Method (paper 2.1 and 3 find these automatically; refs. [18, 19] use circle
transforms):

1. **Start.** The image circle is the bright disc inside a dark border: a
   threshold of the smoothed, downscaled image, its largest blob, and a circle
   fitted to its outline where it meets its convex hull, away from the frame's
   edges (the visible arcs of a circle the frame cuts, not the dents of dark
   scene). Where that does not convince, a
   gradient circle transform of the downscaled image gives candidates: strong
   edges vote along their gradient for a centre, then for a radius.
2. **Rim edge points.** Along 720 rays from that centre, the intensity profile
   across the rim is sampled at full resolution (bilinear) and smoothed along
   the ray; each ray's outermost clear bright-to-dark drop is located to a
   fraction of a pixel. Only drops whose neighbourhood lies in the frame count:
   the frame's border is no rim.
3. **Robust circle fit.** A consensus circle through three edge points (seeded
   RANSAC), then geometric least squares (Gauss-Newton) on the points near it,
   then on the inliers (within 3 robust sigmas); steps 2-3 repeat from the new
   centre. A rim must be seen on enough rays, all round, and the level must step
   across it on most rays in the frame; that count ranks candidates. An ellipse
   is fitted to the same inliers and reported when the rim is measurably
   elliptical (non-square pixels, a tilted mirror); its centre is then the image
   centre. Only when no bright disc is found, a rim of either polarity (a mirror
   in a bright housing: darker inside on some arcs, a thin bright or dark line on
   others), started from the circle transform's centres with the radii where the
   edge strength most rays reach peaks, outermost first (a concentric search; the
   centre searched on grids where those centres are too far off): peaks of the
   gradient magnitude along the rays, located on the profile itself (a line at its
   extreme level, a step at its steepest slope), an edge or line standing out on
   the circle, running along it, on most rays (on fewer where it is the last edge,
   the image past it smooth); the outermost such circle. Then a rim darker inside than out, checked by its step alone.
4. **Cut-off disc.** The radius where the median over the rays of the radial
   gradient rises most (a dark self-reflection, textured or not, against the
   scene), then each ray's steepest rise near it, fitted the same way. A
   fisheye, whose centre sees the scene, has none.

Every failure is an error with a reason, never a guess; where no rim is visible
at all, the error (:class:`NoImageCircle`) carries the frame centre as a
starting value.
"""

from __future__ import annotations

import functools
import math
import threading
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from ..errors import PanomapError
from ..geometry import FloatArray, pixel_polar
from ..strips import Ahead

RAYS = 720
COARSE_SIDE = 400
STEP = 0.5  # px between profile samples
PROFILE_SIGMA_PX = 1.0  # smoothing of the profiles along their rays
# Samples either side of an edge (4 px) that must lie in the frame, and those whose levels are compared.
EDGE_HALF_WINDOW = 8
LEVEL_SAMPLES = 16
# Edge points further than this from the fitted circle (in robust sigmas) are outliers.
INLIER_SIGMAS = 3.0
# Rays (of RAYS) whose rim points must agree: a circle cut by the frame by 15% of its
# radius on two sides still shows 64% of its rim, but dark scene may hide much of that
# (a real fisheye cut at top and bottom shows a quarter of its rim).
MIN_RIM_FRACTION = 0.2
# A round image just larger than the frame (past a square frame's sides, or a 4:3 frame's four) shows its rim only
# about the corners, on fewer rays than that: there, this share of the rays on which the circle lies in the frame
# will do, and no fewer than MIN_RIM_RAYS (20 deg of rim, in the sectors asked for below).
MIN_RIM_SHARE_IN_FRAME = 0.6
MIN_RIM_RAYS = 40
# ... spread around the circle: in at least this many of 12 sectors of 30 deg, a third of the rays agree.
MIN_RIM_SECTORS = 4
# Rays (of those in the frame) stepping across a rim that needs no other candidate.
CONVINCING_RIM_FRACTION = 0.85
# Rays (of those in the frame) along which the level steps across the circle: 0.8-0.97 on
# real rims, 0.4-0.7 on circles through scene edges. A mirror's rim in a bright housing
# (darker inside than out) steps less clearly (0.5-0.8 on the real one), and circles
# through scene edges reach 0.53 there.
MIN_STEPPING_FRACTION = 0.75
MIN_STEPPING_FRACTION_DARK_INSIDE = 0.62
# A search stops after its first circle where the levels step across it on fewer than this
# share of the rays the final test asks for (a wrong start costs one search, not four).
EARLY_STEPPING_SHARE = 0.5
# A rim of either polarity (a mirror in a bright housing) is told from scene edges by an edge
# or line that stands out on it (FEATURE_MIN_STRENGTH grey levels per px, FEATURE_MIN_RATIO
# times the edges beside it) on this fraction of the rays in the frame, in this many sectors.
MIN_FEATURE_FRACTION = 0.6
# ... or this fraction, for a circle about the same centre past one that passed (the outermost is the rim).
MIN_FEATURE_FRACTION_OUTSIDE = 0.4
MIN_RIM_SECTORS_EITHER = 6
# ... or this fraction, in MIN_RIM_SECTORS, for such a circle where the image past it is smooth
# (the housing out of focus; a rim seen only where the housing's light differs from the mirror's:
# on 22-38% of the rays where it is as bright as the mirror on 62% of the rim).
MIN_FEATURE_FRACTION_LAST = 0.2
FEATURE_MIN_STRENGTH = 4.0
FEATURE_MIN_RATIO = 2.0
# Sharp real rims fit to 0.2-0.9 px RMS, a soft (vignetted) one to 1.5 px; a false circle
# through scene edges fits worse.
MAX_RIM_RMS_PX = 2.0
# A soft rim (a fisheye's field stop out of focus, blurred over several px) scatters its edge points: each
# ray's outermost clear drop falls anywhere on the long slope, outward on average (a stop blurred by 3-4 px:
# 0.5-1.7 px RMS, the centre up to 0.9 px off and the radius up to 1.5 px too large; the whole image blurred
# by 8 px: none passes). A bright- or dark-inside rim whose fit is worse than SOFT_RIM_RMS_PX is fitted again
# on the image smoothed by each of SOFT_RIM_SIGMAS_PX (the profiles then show one slope), kept where its RMS
# is under SOFT_RIM_GAIN of the first and it is the same edge (centre and radius each within twice the
# first's RMS: on one real fisheye image the smoothed fit took an edge 4 px further in).
SOFT_RIM_RMS_PX = 0.5
SOFT_RIM_SIGMAS_PX = (2.0, 4.0)
SOFT_RIM_GAIN = 0.7
MIN_CUTOFF_FRACTION = 0.5
MAX_CUTOFF_RMS_PX = 1.5
# Median over the rays of the radial gradient (grey levels per px) at the cut-off disc's edge.
CUTOFF_MIN_MEDIAN_RISE = 3.0
# The cut-off disc's centre may lie this far (a fraction of the outer radius) from the rim's: on the
# miniomni camera the disc (about the calibrated axis) is 3-5 px off the rim's centre in most images.
CUTOFF_CENTRE_FRACTION = 0.03
CUTOFF_ITERATIONS = 4
# A mirror image that overfills the frame shows no rim, only the camera's reflection: a dark disc
# near the frame's middle. It is looked for about a grid of centres this far (a fraction of the
# frame's short side, in steps of DISC_GRID_STEP) from the middle, and kept only where it is clear:
# a dark-to-bright edge on DISC_MIN_FRACTION of the rays, its centre within DISC_MAX_OFFSET and its
# radius within DISC_RADII of the short side (on 40 simulated full-frame fisheyes, none was found).
DISC_GRID_HALF = 0.03
DISC_GRID_STEP = 0.005
DISC_MIN_FRACTION = 0.7
DISC_MAX_OFFSET = 0.05
DISC_RADII = (0.02, 0.35)
DISC_CANDIDATES = 5
# An ellipse is reported when its axes differ by more than this fraction and it fits clearly better.
ELLIPSE_MIN_ECCENTRICITY = 0.003
# The circle transform: the strongest edge pixels that vote, and the weakest gradient (Sobel units) that may.
VOTING_EDGES = 6000
VOTING_MIN_GRADIENT = 20.0
# How far (a fraction of the radius) the rim is looked for from a start circle: a good one, a rough one.
NARROW_REACH = 0.06
WIDE_REACH = 0.15
# A drop of at least this fraction of the steepest on its ray is a clear one.
CLEAR_DROP = 0.3
# Circles through three edge points tried by the consensus fit.
CONSENSUS_SAMPLES = 200
GAUSS_NEWTON_ITERATIONS = 50
# Edge points this close to a circle (px) measure its spread.
NEAR_PX = 3.0
# ... or this fraction of the radius, when more: a rim that is an ellipse strays that far from a circle.
NEAR_FRACTION = 0.015
# The concentric search for a faint rim of either polarity: the circle transform's centres it
# starts from, its rays, the fraction of them whose edge strength it takes at each radius, and
# what makes a peak of that profile clear (a fraction of the highest, a multiple of its median).
CONCENTRIC_SEEDS = 3
CONCENTRIC_RAYS = 72
# Where those centres give no rim, the grids (half-width, step; px) on which the centre is searched.
CONCENTRIC_GRIDS = ((40.0, 10.0), (10.0, 3.0), (3.0, 1.0))
# ... scored by its profile's highest peak, and again by how far a peak stands above the profile's
# running median over this many px of radius either side (in the shrunk image): a rim is narrow in radius.
CONCENTRIC_BACKGROUND_PX = 12.0
CONCENTRIC_SHARE = 0.4
# ... of the rays in the frame, at radii where at least this fraction of them are.
CONCENTRIC_LEAST_IN_FRAME = 0.2
CONCENTRIC_PEAK_RATIO = 0.3
CONCENTRIC_PROMINENCE = 3.0
# Two start circles whose centres and radii differ by less than this fraction of the radius
# (or 2 px) lead to the same rim: the second is not tried.
SAME_START_FRACTION = 0.01
FRAME_EDGES = ("left", "top", "right", "bottom")


class NoImageCircle(PanomapError):
    """No rim is visible: a full-frame fisheye, a mirror image that overfills the frame, an ordinary photo
    or a blank image.

    Attributes
    ----------
    frame_centre : (u, v)
        The middle of the frame, px: a starting value for a centre that the
        landmarks then refine.
    cutoff : Circle or None
        The cut-off disc, where one shows without a rim (a mirror camera whose
        image overfills the frame): its centre is the better starting value.
    """

    def __init__(
        self,
        message: str,
        frame_centre: tuple[float, float],
        source: object | None = None,
        cutoff: Circle | None = None,
    ) -> None:
        super().__init__(message, source)
        self.frame_centre = frame_centre
        self.cutoff = cutoff


@dataclass(frozen=True)
class Circle:
    """A fitted circle.

    Attributes
    ----------
    centre : (u, v), px
    radius : float, px
    rms_px : float
        RMS distance of the inlier edge points from the circle.
    inliers, rays : int
        Edge points used, out of the rays cast.
    """

    centre: tuple[float, float]
    radius: float
    rms_px: float
    inliers: int
    rays: int

    def to_dict(self) -> dict[str, Any]:
        return {
            "centre": list(self.centre),
            "radius": self.radius,
            "rms_px": self.rms_px,
            "inliers": self.inliers,
            "rays": self.rays,
        }


@dataclass(frozen=True)
class Ellipse:
    """An ellipse fitted to the rim: centre (px), semi-axes (px), angle of the first axis (deg)."""

    centre: tuple[float, float]
    semi_axes: tuple[float, float]
    angle_deg: float

    def to_dict(self) -> dict[str, Any]:
        return {"centre": list(self.centre), "semi_axes": list(self.semi_axes), "angle_deg": self.angle_deg}


@dataclass(frozen=True)
class ImageCircles:
    """What :func:`find_image_circles` found.

    The valid region of the image is the image circle intersected with the frame.

    Attributes
    ----------
    centre : (u0, v0)
        The image centre: the rim's centre (the ellipse's, when it is one).
    outer : Circle
        The image circle.
    cutoff : Circle or None
        The self-occlusion disc; None when there is none (a fisheye).
    ellipse : Ellipse or None
        The rim as an ellipse, when it measurably is one.
    cropped_by : tuple of str
        The frame edges that cut the image circle, of ``FRAME_EDGES`` (left, top,
        right, bottom); empty when the whole circle is in the frame.
    rim_in_frame : float
        Fraction of the circle's circumference inside the frame.
    rim_seen : float
        Fraction of the rays (all around) on which the rim was found and agrees
        with the circle: at most ``rim_in_frame``, less where dark scene touches it.
    rim_polarity : str
        ``'bright inside'`` (a bright disc in a dark border); for a rim found by its
        edge of either polarity (a mirror in a bright housing), ``'dark inside'`` where
        the level steps up across it on most of the rays that step, else ``'mixed'``
        (darker inside on some arcs, brighter or a thin line on others).
    rim_arcs_deg : tuple of (start, end)
        The arcs of the rim the circle was fitted to, in image angle (deg, from +u
        towards +v), ``start < end``, ``end`` past 360 for an arc across 0 deg.
    """

    centre: tuple[float, float]
    outer: Circle
    cutoff: Circle | None
    ellipse: Ellipse | None
    cropped_by: tuple[str, ...] = ()
    rim_in_frame: float = 1.0
    rim_seen: float = 1.0
    rim_polarity: str = "bright inside"
    rim_arcs_deg: tuple[tuple[float, float], ...] = ()

    @property
    def outer_radius(self) -> float:
        return self.outer.radius

    @property
    def cutoff_radius(self) -> float | None:
        return None if self.cutoff is None else self.cutoff.radius

    def to_dict(self) -> dict[str, Any]:
        return {
            "centre": list(self.centre),
            "outer_radius": self.outer_radius,
            "cutoff_radius": self.cutoff_radius,
            "outer": self.outer.to_dict(),
            "cutoff": None if self.cutoff is None else self.cutoff.to_dict(),
            "ellipse": None if self.ellipse is None else self.ellipse.to_dict(),
            "cropped_by": list(self.cropped_by),
            "rim_in_frame": self.rim_in_frame,
            "rim_seen": self.rim_seen,
            "rim_polarity": self.rim_polarity,
            "rim_arcs_deg": [list(arc) for arc in self.rim_arcs_deg],
        }


def to_grey(image: NDArray[Any]) -> NDArray[Any]:
    """(H, W) float32 grey levels on a 0..255 scale, from 8- or 16-bit, 1, 3 or 4 channels."""
    scale = 255.0 / 65535.0 if image.dtype == np.uint16 else 1.0
    if image.ndim == 3 and image.shape[2] >= 3:
        grey = cv2.cvtColor(image[..., :3], cv2.COLOR_BGR2GRAY)
    else:
        grey = image.reshape(image.shape[0], image.shape[1])
    return grey.astype(np.float32) * np.float32(scale) if scale != 1.0 else grey.astype(np.float32)


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
    grey = to_grey(image)
    height, width = grey.shape
    frame_centre = ((width - 1) / 2, (height - 1) / 2)
    if min(height, width) < 32:
        raise NoImageCircle(
            f"no image circle found: the image is too small ({width} x {height}) to find an image circle in",
            frame_centre,
        )
    small, factor = _downscaled(grey)
    reasons: list[str] = []
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
    while best is not None and best.polarity == 0:
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
    if best is None:
        best = _soft_start(grey, small, factor, reasons)
    elif best.polarity != 0 and best.circle.rms_px > SOFT_RIM_RMS_PX:
        best = _soft_rim(grey, best)
    if best is None:
        reason = next((r for r in reasons if "rim" in r), reasons[0] if reasons else "no rim")
        disc = _disc_without_rim(grey, small, factor)
        if disc is not None:
            raise NoImageCircle(
                f"{reason}; no rim is visible, but a cut-off disc is (the camera's own reflection: a mirror "
                f"image that overfills the frame), centre ({disc.centre[0]:.1f}, {disc.centre[1]:.1f}), "
                f"radius {disc.radius:.1f} px: its centre is only a starting value",
                frame_centre,
                cutoff=disc,
            )
        raise NoImageCircle(
            f"{reason}; no rim is visible (a full-frame fisheye, or not an omni-image): "
            f"the frame centre ({frame_centre[0]:.1f}, {frame_centre[1]:.1f}) is only a starting value",
            frame_centre,
        )
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


def _soft_start(grey: NDArray[Any], small: NDArray[Any], factor: int, reasons: list[str]) -> _Rim | None:
    """Where no rim passed: a bright disc's rim looked for again on the image smoothed by the widest of
    SOFT_RIM_SIGMAS_PX (a rim too soft for its edge points to lie on a circle at full sharpness); None if none."""
    try:
        candidates = _coarse_circle(small, factor)
    except PanomapError:
        return None
    smooth = cv2.GaussianBlur(grey, (0, 0), SOFT_RIM_SIGMAS_PX[-1])
    return _best_rim(smooth, candidates, 1, (NARROW_REACH, WIDE_REACH), False, None, [], reasons)


@dataclass(frozen=True)
class _Rim:
    """A rim found: its circle, its edge points (n, 2), how many rays fall in the frame, its polarity.

    ``stepping`` counts the rays that cross a step across the circle (the levels
    just inside and just outside it differ), edge or not: what ranks candidates.
    """

    circle: Circle
    points: FloatArray
    rays_in_frame: float
    polarity: int
    stepping: int

    @property
    def convincing(self) -> bool:
        """Whether the level steps across the circle on so many rays that no other candidate is needed."""
        return self.stepping >= CONVINCING_RIM_FRACTION * self.rays_in_frame

    @property
    def rank(self) -> float:
        """Which of two rims to keep: the one with more stepping rays (with a rim's edge or line, for
        polarity 0); of dark-inside ones, the larger."""
        return self.stepping if self.polarity >= 0 else self.circle.radius


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
    return _Rim(circle, points, in_frame, polarity, stepping)


def _least_rim_rays(centre: tuple[float, float], radius: float, shape: tuple[int, int], polarity: int) -> float:
    """Rays (of RAYS) whose edge points a rim about ``centre`` of ``radius`` (px) needs: MIN_RIM_FRACTION of
    them, or, where the frame shows less of the circle, MIN_RIM_SHARE_IN_FRAME of those it shows (at least
    MIN_RIM_RAYS). Not for a rim of either polarity (``polarity`` 0), which no step across it confirms: a
    mirror in a housing, whose rim the frame does not cut that much."""
    if not polarity:
        return MIN_RIM_FRACTION * RAYS
    shown = _fraction_in_frame(centre, radius, shape) * RAYS
    return max(MIN_RIM_RAYS, min(MIN_RIM_FRACTION * RAYS, MIN_RIM_SHARE_IN_FRAME * shown))


def _smooth_beyond(grey: NDArray[Any], circle: Circle) -> bool:
    """Whether the image past the circle (4 px to WIDE_REACH of the radius) has no clear edge on most rays.

    Past a mirror's rim lies its housing, out of focus; past a circle of the scene inside
    the mirror, the rest of the mirror. On each ray the strongest edge there (smoothed as
    for the rim) is taken; their median over the rays seen there must stay under
    FEATURE_MIN_STRENGTH, and half the rays must be seen there.
    """
    radii = np.arange(circle.radius + 4.0, circle.radius * (1 + WIDE_REACH), STEP)
    samples, _, _ = _profiles(grey, circle.centre, radii, RAYS // 4)
    strength = np.where(np.isfinite(samples), _edge_strength(samples), np.nan)
    seen = np.sum(np.isfinite(samples), axis=1) >= 0.5 * len(radii)
    if seen.sum() < 0.5 * len(seen):
        return False
    strongest = np.nanmax(strength[seen], axis=1)
    return bool(np.median(strongest) < FEATURE_MIN_STRENGTH)


def _stepping_rays(grey: NDArray[Any], circle: Circle, polarity: int) -> int:
    """Rays along which the level 2-12 px inside the circle exceeds that 2-12 px outside by 8 grey levels."""
    radii = circle.radius + np.concatenate([np.arange(-12.0, -2.0, STEP), np.arange(2.5, 12.5, STEP)])
    samples, _, _ = _profiles(grey, circle.centre, radii)
    half = samples.shape[1] // 2
    inside, outside = _row_medians(samples[:, :half]), _row_medians(samples[:, half:])
    with np.errstate(invalid="ignore"):
        return int(np.sum(polarity * (inside - outside) > 8.0))


def _edge_strength(samples: NDArray[Any]) -> FloatArray:
    """Gradient magnitude along each ray (grey levels per px), smoothed along it (sigma 2 px); 0 outside the frame.

    Either polarity: a step up or down gives a peak at the step, and a thin bright or dark
    line (its two opposite slopes merged by the smoothing) a peak at its middle.
    """
    gradient = np.abs(np.gradient(samples, axis=1)) / STEP
    gradient = np.where(np.isfinite(gradient), gradient, 0.0).astype(np.float32)
    return np.asarray(cv2.GaussianBlur(gradient, (17, 1), 2.0 / STEP, borderType=cv2.BORDER_REPLICATE), np.float64)


def _feature_rays(grey: NDArray[Any], circle: Circle) -> int:
    """Rays on which an edge or a line, of either polarity, stands out on the circle.

    On each ray the strongest edge within 1.5 px of the circle must reach FEATURE_MIN_STRENGTH
    and FEATURE_MIN_RATIO times the median edge strength 4-12 px either side of it: a
    rim's edge stands out from the smooth mirror and housing beside it, while a circle
    through scene edges meets an edge only where it crosses one.
    """
    radii = circle.radius + np.arange(-14.0, 14.0 + STEP / 2, STEP)
    samples, _, _ = _profiles(grey, circle.centre, radii)
    strength = _edge_strength(samples)
    # Across the rays (1 px along the circle either way): a rim's edge runs along the circle.
    turn = 1.0 / circle.radius
    ahead, _, _ = _profiles(grey, circle.centre, radii, turn_rad=turn)
    behind, _, _ = _profiles(grey, circle.centre, radii, turn_rad=-turn)
    across = np.abs(ahead - behind) / 2
    across = np.where(np.isfinite(across), across, 0.0).astype(np.float32)
    across = cv2.GaussianBlur(across, (17, 1), 2.0 / STEP, borderType=cv2.BORDER_REPLICATE)
    offset = np.abs(radii - circle.radius)
    near = np.flatnonzero(offset <= 1.5)
    index = near[np.argmax(strength[:, near], axis=1)]
    rows = np.arange(RAYS)
    on = strength[rows, index]
    beside = np.median(strength[:, (offset >= 4) & (offset <= 12)], axis=1)
    in_frame = np.all(np.isfinite(samples[:, offset <= 12]), axis=1)
    along = on >= FEATURE_MIN_RATIO * across[rows, index]
    return int(np.sum(in_frame & along & (on >= FEATURE_MIN_STRENGTH) & (on >= FEATURE_MIN_RATIO * beside)))


def _either_polarity(grey: NDArray[Any], circle: Circle) -> str:
    """``'dark inside'`` when the level steps up across the circle on most of the rays that step, else ``'mixed'``."""
    up = _stepping_rays(grey, circle, -1)
    down = _stepping_rays(grey, circle, 1)
    return "dark inside" if up >= CONVINCING_RIM_FRACTION * (up + down) else "mixed"


def _sectors_seen(points: FloatArray, circle: Circle) -> int:
    """Sectors of 30 deg (of 12) in which at least a third of the rays have a point on the circle."""
    du, dv = points[:, 0] - circle.centre[0], points[:, 1] - circle.centre[1]
    on = np.abs(np.hypot(du, dv) - circle.radius) < max(INLIER_SIGMAS * circle.rms_px, 0.5)
    sector = (np.floor(np.arctan2(dv[on], du[on]) / (math.pi / 6)).astype(np.int64)) % 12
    return int(np.sum(np.bincount(sector, minlength=12) >= RAYS / 12 / 3))


def _arcs(points: FloatArray, circle: Circle) -> tuple[tuple[float, float], ...]:
    """The arcs (start, end deg) the points on the circle cover: gaps up to 2 deg bridged, arcs under 2 deg dropped."""
    du, dv = points[:, 0] - circle.centre[0], points[:, 1] - circle.centre[1]
    on = np.abs(np.hypot(du, dv) - circle.radius) < max(INLIER_SIGMAS * circle.rms_px, 0.5)
    seen = np.zeros(360, dtype=bool)
    seen[np.floor(np.degrees(np.arctan2(dv[on], du[on])) % 360).astype(np.int64) % 360] = True
    if seen.all():
        return ((0.0, 360.0),)
    # Bridge gaps of up to 2 deg, then read the runs from the first degree not seen.
    bridged = seen | (np.roll(seen, 1) & np.roll(seen, -2)) | (np.roll(seen, 2) & np.roll(seen, -1))
    start = int(np.argmin(bridged))
    runs, begin = [], None
    for k in range(start, start + 361):
        if bridged[k % 360] and begin is None:
            begin = k
        elif not bridged[k % 360] and begin is not None:
            if k - begin >= 2:
                runs.append((float(begin % 360), float(begin % 360 + k - begin)))
            begin = None
    return tuple(sorted(runs))


def _downscaled(grey: NDArray[Any]) -> tuple[NDArray[Any], int]:
    """The image shrunk by an integer factor to at most COARSE_SIDE px a side, smoothed; and that factor."""
    height, width = grey.shape
    factor = max(1, math.ceil(max(height, width) / COARSE_SIDE))
    small = cv2.resize(grey, (width // factor, height // factor), interpolation=cv2.INTER_AREA)
    return cv2.GaussianBlur(small, (0, 0), 1.5), factor


def _full_resolution(point: tuple[float, float], factor: int) -> tuple[float, float]:
    """A position in the downscaled image in full-resolution px: sample k is at (k + 0.5) * factor - 0.5."""
    return (point[0] + 0.5) * factor - 0.5, (point[1] + 0.5) * factor - 0.5


def _voted_circles(
    small: NDArray[Any], factor: int, polarity: int, count: int = 3
) -> list[tuple[tuple[float, float], float]]:
    """Up to ``count`` circles of a gradient circle transform of the downscaled image.

    Each strong edge pixel votes for centres along its gradient, on the bright side
    (``polarity`` +1: a disc brighter than its surround), the dark side (-1) or both (0), at
    every distance a rim may have; the strongest centres get the radius most of their
    edges point from. Its cost is bounded by the number of edge pixels kept, whatever
    the scene.
    """
    height, width = small.shape
    gx = cv2.Sobel(small, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(small, cv2.CV_32F, 0, 1, ksize=3)
    magnitude = np.hypot(gx, gy).ravel()
    if polarity:
        keep = min(VOTING_EDGES, magnitude.size // 8)
        strongest = np.argpartition(magnitude, -keep)[-keep:]
        strongest = strongest[magnitude[strongest] > VOTING_MIN_GRADIENT]
    else:
        # A rim of either polarity may be fainter than the scene's edges (a thin line, a
        # soft step): edges drawn at random among all clear ones, not the strongest, vote.
        strongest = np.flatnonzero(magnitude > VOTING_MIN_GRADIENT)
        if len(strongest) > VOTING_EDGES // 2:  # each votes twice
            strongest = np.sort(np.random.default_rng(0).choice(strongest, VOTING_EDGES // 2, replace=False))
    if len(strongest) < 50:
        raise PanomapError("no image circle found: the image has almost no edges")
    y, x = np.divmod(strongest, width)
    weight = magnitude[strongest]
    dx = gx.ravel()[strongest] / weight
    dy = gy.ravel()[strongest] / weight
    if polarity:
        dx, dy = polarity * dx, polarity * dy
    else:  # either side: each edge votes both ways
        x, y, weight = np.tile(x, 2), np.tile(y, 2), np.tile(weight, 2)
        dx, dy = np.concatenate([dx, -dx]), np.concatenate([dy, -dy])
    r_min, r_max = 0.2 * min(height, width), 0.75 * max(height, width)
    # Votes every 1.5 px into cells of 2 x 2 px: the centre need only be good enough to start from.
    # In float32 and cell units throughout (2.5x faster than float64 px): a vote's cell is its
    # position halved, truncated where it is not negative.
    half_distances = np.arange(r_min, r_max, 1.5, dtype=np.float32) / 2
    cells = (height + 1) // 2, (width + 1) // 2
    cu = (x.astype(np.float32) / 2)[:, None] + half_distances[None, :] * dx.astype(np.float32)[:, None]
    cv = (y.astype(np.float32) / 2)[:, None] + half_distances[None, :] * dy.astype(np.float32)[:, None]
    inside = (cu >= 0) & (cu < cells[1]) & (cv >= 0) & (cv < cells[0])
    cell = cv[inside].astype(np.int32) * cells[1] + cu[inside].astype(np.int32)
    votes = np.bincount(cell, minlength=cells[0] * cells[1]).astype(np.float32)
    accumulator = cv2.GaussianBlur(votes.reshape(cells), (0, 0), 1.0)
    candidates = []
    for _ in range(count):
        cell_v, cell_u = np.unravel_index(int(np.argmax(accumulator)), accumulator.shape)
        if accumulator[cell_v, cell_u] <= 0:
            break
        cv2.circle(accumulator, (int(cell_u), int(cell_v)), max(2, round(min(cells) / 10)), 0.0, -1)
        peak_u, peak_v = 2 * cell_u + 0.5, 2 * cell_v + 0.5
        # The radius: the distance most of the edges pointing at this centre lie at.
        to_u, to_v = peak_u - x, peak_v - y
        distance = np.hypot(to_u, to_v)
        with np.errstate(invalid="ignore", divide="ignore"):
            aligned = (to_u * dx + to_v * dy) / distance > 0.95
        aligned &= (distance >= r_min) & (distance < r_max)
        if aligned.sum() < 20:
            continue
        histogram = np.bincount(np.rint(distance[aligned]).astype(np.int64), weights=weight[aligned])
        radius = float(np.argmax(np.convolve(histogram, np.ones(3) / 3, mode="same")))
        candidates.append((_full_resolution((float(peak_u), float(peak_v)), factor), radius * factor))
    return candidates


def _concentric_circles(
    grey: NDArray[Any], seeds: list[tuple[float, float]], count: int = 1
) -> list[tuple[tuple[float, float], float]]:
    """Circles (full-resolution px) about rough centres on which an edge of either polarity lies all round.

    The circle transform of the downscaled image finds the centre of a faint rim (a
    thin line, a soft step in a bright housing) to a few px, but its radius is that of
    the strongest circle about that centre, often one of the scene inside a mirror
    (a ceiling's edge). About each seed the edge strength (at full resolution, smoothed
    along the rays as the rim points are) that CONCENTRIC_SHARE of all the rays reach is a
    profile over the radius (a ray off the frame has none): it peaks where an edge lies at
    one radius all round, while scene edges spread over many radii (Daugman's
    integro-differential operator, with a quantile for a rim whose contrast changes sign).
    Its clear peaks (CONCENTRIC_PEAK_RATIO of the highest, CONCENTRIC_PROMINENCE times its
    median) are the candidate radii, outermost first, ``count`` per seed: the rim is the
    outermost circle. Then the same from the share of the rays in the frame
    (:func:`_share_reached`), for a circle that the frame cuts on every side; those
    candidates come after all the others (the real MiniOmni images lose rims found by the
    first profile where the second one's candidates come first).
    """
    height, width = grey.shape
    radii = np.arange(0.2 * min(height, width), 0.75 * max(height, width), STEP)
    share = int((1 - CONCENTRIC_SHARE) * CONCENTRIC_RAYS)
    first: list[tuple[tuple[float, float], float]] = []
    then: list[tuple[tuple[float, float], float]] = []
    for seed in seeds:
        samples, _, _ = _profiles(grey, seed, radii, CONCENTRIC_RAYS)
        strength = np.where(np.isfinite(samples), _edge_strength(samples), np.nan)
        for profile, found in (
            (np.partition(np.nan_to_num(strength), share, axis=0)[share], first),
            (_share_reached(strength, axis=0), then),
        ):
            top = float(profile.max())
            if top <= 0:
                continue
            peak = (profile[1:-1] >= profile[:-2]) & (profile[1:-1] > profile[2:])
            least = max(CONCENTRIC_PEAK_RATIO * top, CONCENTRIC_PROMINENCE * float(np.median(profile)))
            indices = np.flatnonzero(peak & (profile[1:-1] >= least)) + 1
            found += [(seed, float(radii[index])) for index in indices[::-1][:count]]
    return first + [c for c in then if not any(c[0] == o[0] and abs(c[1] - o[1]) < NEAR_PX for o in first)]


def _outermost_edge_circle(
    grey: NDArray[Any], seed: tuple[float, float], radius: float
) -> list[tuple[tuple[float, float], float]]:
    """The consensus circle (full-resolution px) through the outermost clear edge on each ray from ``seed``.

    The rim is the outermost circle: past it, a housing out of focus. Where the circle
    transform's centre is 20-30 px off a thin rim line at 1920 px (the line faint in the
    shrunk image), no profile about that centre, or about the grid search's, shows the rim;
    the outermost edge of either polarity (FEATURE_MIN_STRENGTH grey levels per px, a local
    peak, 8 px or more inside the frame's edge) lies on the rim on most rays whatever the
    centre, and a consensus circle through those points starts the rim's search. Empty
    where fewer than MIN_RIM_FRACTION of the rays have one.
    """
    height, width = grey.shape
    radii = np.arange(0.2 * min(height, width), 0.75 * max(height, width), STEP)
    rays = RAYS // 2  # points enough for the consensus, at half the cost where there is no rim
    samples, cos, sin = _profiles(grey, seed, radii, rays)
    inside = np.isfinite(samples)
    strength = np.where(inside, _edge_strength(samples), 0.0)
    # Away from where the ray leaves the frame (the frame's own edge).
    margin = round(8 / STEP)
    last = radii.size - 1 - np.argmax(inside[:, ::-1], axis=1)
    usable = np.arange(radii.size)[None, :] < (last - margin)[:, None]
    peak = np.zeros_like(inside)
    peak[:, 1:-1] = (strength[:, 1:-1] >= strength[:, :-2]) & (strength[:, 1:-1] > strength[:, 2:])
    peak &= usable & inside & (strength >= FEATURE_MIN_STRENGTH)
    has = peak.any(axis=1)
    if has.sum() < MIN_RIM_FRACTION * rays:
        return []
    outermost = radii.size - 1 - np.argmax(peak[:, ::-1], axis=1)
    reach = radii[outermost[has]]
    points = np.stack([seed[0] + cos[has] * reach, seed[1] + sin[has] * reach], axis=1)
    centre, found = _consensus_circle(points, seed, radius)
    return [(centre, found)]


def _share_reached(strength: NDArray[Any], axis: int) -> FloatArray:
    """The edge strength that CONCENTRIC_SHARE of the rays in the frame reach, over ``axis`` (the rays; NaN: off
    the frame); 0 where fewer than CONCENTRIC_LEAST_IN_FRAME of the rays are in it.

    Of the rays in the frame, not of all: a round image larger than the frame shows its rim
    on a third of the rays or less (cut by all four edges of a square frame by 12% of its
    radius: 37%), and a share of all the rays never reached it.
    """
    ordered = np.sort(strength, axis=axis)  # NaN last
    count = np.sum(np.isfinite(strength), axis=axis)
    index = np.minimum((1 - CONCENTRIC_SHARE) * count, np.maximum(count - 1, 0)).astype(np.int64)
    reached = np.take_along_axis(ordered, np.expand_dims(index, axis), axis=axis).squeeze(axis)
    enough = count >= CONCENTRIC_LEAST_IN_FRAME * strength.shape[axis]
    return np.where(enough & np.isfinite(reached), reached, 0.0)


def _concentric_centres(grey: NDArray[Any], seed: tuple[float, float]) -> list[tuple[float, float]]:
    """Centres near ``seed`` (within CONCENTRIC_GRIDS[0][0] px) about which edges line up best on circles.

    Where the circle transform's centre is too far off (tens of px) for the rim to give a
    peak in :func:`_concentric_circles`' profile, the centre is searched for on grids of
    shrinking step, in the image shrunk by area to at most COARSE_SIDE px a side (not
    smoothed, so that a thin line survives), by two scores of the profile, each giving one
    centre: its highest peak, and the peak that stands highest above the profile's running
    median (CONCENTRIC_BACKGROUND_PX either side). A rim is narrow in radius about its own
    centre, while a scene's edges (a checkerboard, a room's corners) spread over many radii:
    by height alone, a housed mirror's rim about a seed 10 px off lost to a checkerboard's
    border about a centre 60 px off (OpenCV 5.1's render of the test scene). By prominence
    alone, two real MiniOmni images lost their rim to the scene's edges, which height found.
    Both are kept, the highest peak's first; the same centre once.
    """
    from scipy.ndimage import median_filter  # here, not at the top: importing SciPy is slow

    full_height, full_width = grey.shape
    factor = max(1, math.ceil(max(full_height, full_width) / COARSE_SIDE))
    small = cv2.resize(grey, (full_width // factor, full_height // factor), interpolation=cv2.INTER_AREA)
    height, width = small.shape
    step = 1.5  # px between samples
    rays = CONCENTRIC_RAYS * 2 // 3
    radii = np.arange(0.2 * min(height, width), 0.75 * max(height, width), step, dtype=np.float32)
    angles = np.linspace(0.0, 2 * math.pi, rays, endpoint=False)
    offsets_u = (np.cos(angles)[:, None] * radii[None, :]).astype(np.float32)
    offsets_v = (np.sin(angles)[:, None] * radii[None, :]).astype(np.float32)
    share = int((1 - CONCENTRIC_SHARE) * rays)
    background_size = 2 * round(CONCENTRIC_BACKGROUND_PX / step) + 1
    start = np.array([(seed[0] + 0.5) / factor - 0.5, (seed[1] + 0.5) / factor - 0.5], dtype=np.float32)
    centres: list[tuple[float, float]] = []
    for prominence in (False, True):
        centre = start
        for half_px, spacing_px in CONCENTRIC_GRIDS:
            half, spacing = half_px / factor, spacing_px / factor
            offsets = np.arange(-half, half + spacing / 2, spacing, dtype=np.float32)
            grid = np.stack(np.meshgrid(offsets, offsets), axis=-1).reshape(-1, 2) + centre
            n = len(grid)
            map_u = (grid[:, 0, None, None] + offsets_u[None]).reshape(n * rays, -1)
            map_v = (grid[:, 1, None, None] + offsets_v[None]).reshape(n * rays, -1)
            samples = cv2.remap(
                small, map_u, map_v, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=np.nan
            )
            strength = np.nan_to_num(np.abs(samples[:, 2:] - samples[:, :-2]))
            strength = strength.reshape(n, rays, -1).transpose(0, 2, 1)
            profiles = np.partition(strength, share, axis=2)[..., share]
            if prominence:
                profiles = profiles - median_filter(profiles, size=(1, background_size), mode="nearest")
            centre = grid[int(np.argmax(profiles.max(axis=1)))]
        found = _full_resolution((float(centre[0]), float(centre[1])), factor)
        if not any(math.dist(found, other) < NEAR_PX for other in centres):
            centres.append(found)
    return centres


def _coarse_circle(small: NDArray[Any], factor: int) -> list[tuple[tuple[float, float], float]]:
    """First centre and radius (full-resolution px) from the largest bright blob of the downscaled image.

    Where the blob is cut by the frame, the circle is fitted to its outline away from
    the frame's edges: the arcs of the rim that are visible.
    """
    dark, bright = (float(level) for level in np.percentile(small, (2, 60)))
    if bright - dark < 10:
        raise PanomapError("no image circle found: the image has no dark border around a brighter disc")
    threshold = dark + 0.25 * (bright - dark)
    mask: NDArray[Any] = (small > threshold).astype(np.uint8)
    mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    if not contours:
        raise PanomapError("no image circle found: nothing stands out from the border")
    contour = max(contours, key=cv2.contourArea)
    area = cv2.contourArea(contour)
    if area < 0.05 * small.size:
        raise PanomapError("no image circle found: the largest bright region is too small")
    points = contour.reshape(-1, 2).astype(np.float64)
    height, width = small.shape
    on_border = (points[:, 0] <= 1) | (points[:, 1] <= 1) | (points[:, 0] >= width - 2) | (points[:, 1] >= height - 2)
    if np.sum(~on_border) < 0.3 * len(points) and _quadrants(points[~on_border], small.shape) < 3:
        # (A round image just past the frame's sides still shows its rim about three or four corners.)
        raise PanomapError("no image circle found: the bright region fills the frame (no rim around it)")
    # Dark scene touching the rim dents the blob; the outline where it meets its convex hull is the rim.
    hull = cv2.convexHull(contour)
    on_hull = np.array([abs(cv2.pointPolygonTest(hull, (float(u), float(v)), True)) < 1.5 for u, v in points])
    arcs = points[on_hull & ~on_border]
    if len(arcs) < 20:
        arcs = points[~on_border]
    (cu, cv), radius = _algebraic_circle(arcs)
    return [(_full_resolution((cu, cv), factor), radius * factor)]


def _quadrants(points: FloatArray, shape: tuple[int, int]) -> int:
    """How many quarters of the frame (about its middle) hold at least 10 of the points (n, 2)."""
    height, width = shape
    quarter = 2 * (points[:, 0] > (width - 1) / 2) + (points[:, 1] > (height - 1) / 2)
    return int(np.sum(np.bincount(quarter.astype(np.int64), minlength=4) >= 10))


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


def _cropping_edges(centre: tuple[float, float], radius: float, shape: tuple[int, int]) -> tuple[str, ...]:
    """The frame edges that cut the circle, in the order left, top, right, bottom."""
    height, width = shape
    u, v = centre
    beyond = (u - radius < -0.5, v - radius < -0.5, u + radius > width - 0.5, v + radius > height - 0.5)
    return tuple(edge for edge, cut in zip(FRAME_EDGES, beyond, strict=True) if cut)


def _sectors_in_frame(circle: Circle, shape: tuple[int, int]) -> int:
    """Sectors of 30 deg (of 12) of the circle in which at least a third of the rays fall in the frame."""
    height, width = shape
    angles = (np.arange(RAYS) + 0.5) * (2 * math.pi / RAYS)
    u = circle.centre[0] + circle.radius * np.cos(angles)
    v = circle.centre[1] + circle.radius * np.sin(angles)
    inside = (u >= -0.5) & (u <= width - 0.5) & (v >= -0.5) & (v <= height - 0.5)
    return int(np.sum(inside.reshape(12, -1).mean(axis=1) >= 1 / 3))


def _fraction_in_frame(centre: tuple[float, float], radius: float, shape: tuple[int, int]) -> float:
    """Fraction of the circle's circumference inside the frame."""
    height, width = shape
    angles = np.linspace(0.0, 2 * math.pi, 3600, endpoint=False)
    u = centre[0] + radius * np.cos(angles)
    v = centre[1] + radius * np.sin(angles)
    return float(np.mean((u >= -0.5) & (u <= width - 0.5) & (v >= -0.5) & (v <= height - 0.5)))


def _profiles(
    grey: NDArray[Any], centre: tuple[float, float], radii: FloatArray, rays: int = RAYS, turn_rad: float = 0.0
) -> tuple[NDArray[Any], FloatArray, FloatArray]:
    """Bilinear samples (rays, R) of ``grey`` along rays at ``radii``, turned by ``turn_rad``; NaN off the image."""
    angles = np.linspace(0.0, 2 * math.pi, rays, endpoint=False) + turn_rad
    cos, sin = np.cos(angles), np.sin(angles)
    map_u = (centre[0] + cos[:, None] * radii[None, :]).astype(np.float32)
    map_v = (centre[1] + sin[:, None] * radii[None, :]).astype(np.float32)
    height, width = grey.shape
    samples = cv2.remap(grey, map_u, map_v, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=np.nan)
    samples[(map_u < 0) | (map_u > width - 1) | (map_v < 0) | (map_v > height - 1)] = np.nan
    # Smoothed along each ray (sigma 1 px; NaN spreads to the samples it touches): far
    # cheaper than smoothing the whole image, and it is across the rim that noise matters.
    return cv2.GaussianBlur(samples, (13, 1), PROFILE_SIGMA_PX / STEP, borderType=cv2.BORDER_REPLICATE), cos, sin


def _subpixel_peak(values: NDArray[Any], index: NDArray[Any]) -> FloatArray:
    """Parabola vertex through samples index-1, index, index+1 of each row (index inside)."""
    rows = np.arange(values.shape[0])
    left, mid, right = values[rows, index - 1], values[rows, index], values[rows, index + 1]
    denominator = left - 2 * mid + right
    with np.errstate(divide="ignore", invalid="ignore"):
        offset = np.where(denominator != 0, 0.5 * (left - right) / denominator, 0.0)
    return index + np.clip(offset, -0.5, 0.5)


def _step_levels(samples: NDArray[Any], index: NDArray[Any]) -> tuple[FloatArray, FloatArray, NDArray[np.bool_]]:
    """Median level just before and just after each row's edge at ``index``, and whether its window is in the frame."""
    rows = np.arange(samples.shape[0])[:, None]
    count = samples.shape[1]
    near = np.clip(index[:, None] + np.arange(-EDGE_HALF_WINDOW, EDGE_HALF_WINDOW + 1)[None, :], 0, count - 1)
    in_frame = np.all(np.isfinite(samples[rows, near]), axis=1)
    in_frame &= (index >= EDGE_HALF_WINDOW) & (index < count - EDGE_HALF_WINDOW)
    offsets = np.arange(4, 4 + LEVEL_SAMPLES)[None, :]
    before = samples[rows, np.clip(index[:, None] - offsets, 0, count - 1)]
    after = samples[rows, np.clip(index[:, None] + offsets, 0, count - 1)]
    return _row_medians(before), _row_medians(after), in_frame


def _row_medians(values: NDArray[Any]) -> FloatArray:
    """Median of each row's finite values (NaN where it has none): ``np.nanmedian(axis=1)``, vectorised."""
    ordered = np.sort(values, axis=1)  # NaN sort last
    count = np.sum(np.isfinite(values), axis=1)
    rows = np.arange(values.shape[0])
    low = ordered[rows, np.maximum(count - 1, 0) // 2]
    high = ordered[rows, np.maximum(count, 1) // 2 - (count == 0)]
    return np.where(count > 0, 0.5 * (low + high), np.nan)


def _rim_points(
    grey: NDArray[Any], centre: tuple[float, float], radius: float, polarity: int, reach: float
) -> FloatArray:
    """Sub-pixel rim edge points (n, 2): the steepest step near ``radius``, from bright to dark going out.

    ``polarity`` -1 looks for the steepest dark-to-bright step instead. Only edges
    whose neighbourhood lies in the frame count: the frame's border is no rim. The
    search runs ``reach`` times the radius either side of it. Each ray's outermost
    clear drop is taken, not its steepest: past the rim the border stays dark, while
    a scene edge inside the disc (a dark target, a checkerboard) may be steeper than
    a soft rim.
    """
    half = max(reach * radius, 8.0)
    radii = np.arange(max(radius - half, 1.0), radius + half, STEP)
    samples, cos, sin = _profiles(grey, centre, radii)
    # The drop in level going out (grey levels per px; a rise for polarity -1), 0 off the
    # image; each pass in place, as these arrays are the search's bulk.
    drops = np.gradient(samples, axis=1)
    np.nan_to_num(drops, copy=False, nan=0.0)
    drops *= np.float32(-polarity / STEP)
    index = np.clip(np.argmax(drops[:, 1:-1], axis=1) + 1, 1, len(radii) - 2)
    rows = np.arange(RAYS)
    middle = drops[:, 1:-1]
    clear = middle > np.maximum(2.0, CLEAR_DROP * drops[rows, index])[:, None]
    clear &= middle >= drops[:, :-2]
    clear &= middle > drops[:, 2:]
    last = clear.shape[1] - 1 - np.argmax(clear[:, ::-1], axis=1)
    index = np.where(clear.any(axis=1), last + 1, index)
    drop = drops[rows, index]
    inside, outside, in_frame = _step_levels(samples, index)
    # A rim: a steep step to something clearly darker (brighter for polarity -1).
    good = in_frame & (drop > 2.0) & (polarity * (inside - outside) > 8.0)
    where = radii[0] + STEP * _subpixel_peak(drops, index)
    r = where[good]
    points = np.stack([centre[0] + r * cos[good], centre[1] + r * sin[good]], axis=-1)
    height, width = grey.shape
    margin = 1.5  # px: the last rows and columns of a frame are often darker or softer
    away = (
        (points[:, 0] > margin)
        & (points[:, 0] < width - 1 - margin)
        & (points[:, 1] > margin)
        & (points[:, 1] < height - 1 - margin)
    )
    return points[away]


def _feature_points(
    grey: NDArray[Any], centre: tuple[float, float], radius: float, reach: float, nearest: bool, beyond: float = 0.0
) -> FloatArray:
    """Sub-pixel rim points (n, 2) of either polarity: peaks of the edge strength near ``radius``.

    A rim whose contrast changes sign around the circle (a mirror in a bright housing:
    darker inside on some arcs, a thin bright or dark line on others) has no one
    polarity to look for. Each ray's clear peaks of the gradient magnitude within
    ``reach`` times the radius either side of it are the candidates: all of them (a
    rough start, for the consensus fit to choose from) or, with ``nearest``, the one
    nearest the start circle on each ray. Only peaks whose neighbourhood lies in the
    frame, and further than ``beyond`` (px) from ``centre``, count.
    """
    half = max(reach * radius, 8.0)
    radii = np.arange(max(radius - half, 1.0, beyond - EDGE_HALF_WINDOW * STEP), radius + half, STEP)
    samples, cos, sin = _profiles(grey, centre, radii)
    strength = _edge_strength(samples)
    rows = np.arange(RAYS)
    middle = strength[:, 1:-1]
    strongest = middle.max(axis=1)
    peak = (middle >= strength[:, :-2]) & (middle > strength[:, 2:])
    peak &= middle > np.maximum(FEATURE_MIN_STRENGTH, CLEAR_DROP * strongest)[:, None]
    # The neighbourhood in the frame: EDGE_HALF_WINDOW samples either way finite.
    finite = np.isfinite(samples).astype(np.float32)
    window = cv2.blur(finite, (2 * EDGE_HALF_WINDOW + 1, 1), borderType=cv2.BORDER_CONSTANT)
    peak &= (window[:, 1:-1] > 1 - 1e-6) & (radii[1:-1] > beyond)[None, :]
    if nearest:
        distance = np.where(peak, np.abs(radii[1:-1] - radius)[None, :], np.inf)
        index = np.argmin(distance, axis=1)
        ray = rows[np.isfinite(distance[rows, index])]
        index = index[ray] + 1
    else:
        ray, index = np.nonzero(peak)
        index = index + 1
    where = radii[0] + STEP * _feature_position(samples[ray], index) if len(ray) else np.zeros(0)
    points = np.stack([centre[0] + where * cos[ray], centre[1] + where * sin[ray]], axis=-1)
    height, width = grey.shape
    margin = 1.5  # px: the last rows and columns of a frame are often darker or softer
    away = (
        (points[:, 0] > margin)
        & (points[:, 0] < width - 1 - margin)
        & (points[:, 1] > margin)
        & (points[:, 1] < height - 1 - margin)
    )
    return np.asarray(points[away], dtype=np.float64)


def _feature_position(samples: NDArray[Any], index: NDArray[Any]) -> FloatArray:
    """Sub-sample position of each row's edge or line found near ``index`` (a peak of the smoothed edge strength).

    The wide smoothing that merges a thin line's two slopes into one peak also pulls that
    peak towards any slope beside it; the position is therefore read from the profile
    itself: a line (slopes of both signs, each at least half the other, within 2 px) at
    its extreme level, a step at its steepest slope, each by a parabola through three samples.
    """
    count = samples.shape[1]
    rows = np.arange(samples.shape[0])
    span = np.arange(-4, 5)
    near = np.clip(index[:, None] + span[None, :], 1, count - 2)
    gradient = np.gradient(samples, axis=1)
    slopes = np.where(np.isfinite(gradient[rows[:, None], near]), gradient[rows[:, None], near], 0.0)
    rise, fall = slopes.max(axis=1), -slopes.min(axis=1)
    line = np.minimum(rise, fall) > 0.5 * np.maximum(rise, fall)
    level = np.where(np.isfinite(samples[rows[:, None], near]), samples[rows[:, None], near], np.nan)
    # A bright line peaks, a dark one dips: the extreme the slopes point to (rise before fall: bright).
    bright = np.argmax(slopes, axis=1) < np.argmin(slopes, axis=1)
    extreme = np.where(
        bright,
        np.nanargmax(np.nan_to_num(level, nan=-np.inf), axis=1),
        np.nanargmin(np.nan_to_num(level, nan=np.inf), axis=1),
    )
    steepest = np.argmax(np.abs(slopes), axis=1)
    at = near[rows, np.where(line, extreme, steepest)]
    at = np.clip(at, 1, count - 2)
    signed = np.where(bright, 1.0, -1.0)[:, None]
    values = np.where(line[:, None], signed * samples, np.abs(gradient))
    return _subpixel_peak(np.where(np.isfinite(values), values, 0.0), at)


def _cutoff_circle(grey: NDArray[Any], centre: tuple[float, float], outer_radius: float) -> Circle | None:
    """The self-occlusion disc: a dark-to-bright step at one radius on most rays; None when there is none.

    The disc's radius is where the median over the rays of the radial gradient peaks,
    so that a textured or lit self-reflection, or scene edges, do not hide it; each
    ray's steepest rise near that radius is then fitted as the rim is.
    """
    # The median over a quarter of the rays finds the radius; all of them then find the edge.
    radii = np.arange(2.0, 0.75 * outer_radius, STEP)
    samples, _, _ = _profiles(grey, centre, radii, RAYS // 4)
    gradient = np.gradient(samples, axis=1) / STEP
    if not np.isfinite(gradient).any():
        return None
    # The median gradient per radius over the rays that are in the frame there.
    score = np.nan_to_num(_row_medians(gradient.T))
    score = np.convolve(score, np.ones(5) / 5, mode="same")
    index = int(np.argmax(score))
    if score[index] < CUTOFF_MIN_MEDIAN_RISE:
        return None
    radius = float(radii[index])

    def passes(circle: Circle | None, reach_px: float) -> bool:
        return (
            circle is not None
            and circle.inliers >= MIN_CUTOFF_FRACTION * RAYS
            and circle.rms_px <= MAX_CUTOFF_RMS_PX
            and math.dist(circle.centre, centre) < reach_px
        )

    circle = _cutoff_edge(grey, centre, radius)
    if passes(circle, max(2.0, 0.05 * radius)):
        return circle
    # The disc is centred on the optical axis, which can sit a few px off the rim's centre (a
    # mirror not quite centred in its housing): its edge is searched for again, first as far
    # either side of the radius as the centres may differ, then about each fit's own centre.
    reach = max(2.0, CUTOFF_CENTRE_FRACTION * outer_radius)
    circle = _cutoff_edge(grey, centre, radius, half_px=reach)
    for _ in range(CUTOFF_ITERATIONS):
        if circle is None:
            return None
        found = _cutoff_edge(grey, circle.centre, circle.radius)
        moved = math.inf if found is None else math.dist(found.centre, circle.centre)
        circle = found
        if moved < 0.05:
            break
    return circle if passes(circle, reach) else None


def find_cutoff_about(image: NDArray[Any], centre: tuple[float, float], outer_radius: float) -> Circle | None:
    """The cut-off disc of an omni-image looked for about ``centre`` (u, v), px, in an image circle of
    ``outer_radius`` px, or None: :func:`find_image_circles`' search about the rim's centre, for a caller
    that knows the optical axis better (a centre refined with landmarks, where the rim's was off)."""
    return _cutoff_circle(to_grey(image), centre, outer_radius)


def find_cutoff_without_rim(image: NDArray[Any]) -> Circle | None:
    """The cut-off disc of an omni-image whose rim is not in it (a mirror image that overfills the frame), or
    None: :func:`find_image_circles`' search where no rim passes (see :func:`_disc_without_rim`), for a caller
    that knows the rim found is wrong (landmarks far outside it)."""
    grey = to_grey(image)
    small, factor = _downscaled(grey)
    return _disc_without_rim(grey, small, factor)


def _disc_without_rim(grey: NDArray[Any], small: NDArray[Any], factor: int) -> Circle | None:
    """The cut-off disc of an image with no rim (a mirror image that overfills the frame); None when none is clear.

    About each centre of a grid near the frame's middle (DISC_GRID_HALF of the short side,
    in steps of DISC_GRID_STEP), in ``small`` (``grey`` shrunk by ``factor``), the median over
    the rays of the radial gradient peaks at the disc's radius, highest about its centre
    (off it, the peak spreads: 5-7 px off a disc of 113-230 px, it fell under the bar that
    :func:`_cutoff_circle` sets, which is why that search alone missed 3 of 10). A camera's
    board about its lens peaks too (its square edge, further out): the DISC_CANDIDATES
    highest peaks of different radii are tried in turn, each edge fitted at full resolution
    from its centre, then about each fit's centre, as the disc of an image with a rim is;
    the first that is clear is kept (DISC_MIN_FRACTION of the rays, within DISC_MAX_OFFSET of
    the middle, a radius within DISC_RADII of the short side).
    """
    height, width = grey.shape
    short = min(height, width)
    middle = ((width - 1) / 2, (height - 1) / 2)
    radii = np.arange(2.0, DISC_RADII[1] * short / factor, STEP)
    steps = round(DISC_GRID_HALF / DISC_GRID_STEP)
    offsets = np.arange(-steps, steps + 1) * DISC_GRID_STEP * short
    starts = [(middle[0] + du, middle[1] + dv) for du in offsets for dv in offsets]
    coarse = (np.asarray(starts) + 0.5) / factor - 0.5
    # (A row of the grid at a time: arrays that stay in the cache.)
    scores = np.concatenate([_median_rise(small, row, radii, RAYS // 8) for row in np.split(coarse, len(offsets))])
    local = (scores[:, 1:-1] >= scores[:, :-2]) & (scores[:, 1:-1] > scores[:, 2:])
    local &= scores[:, 1:-1] >= CUTOFF_MIN_MEDIAN_RISE
    peaks = [  # (score, centre, radius px), in the grid's order
        (float(scores[i, k + 1]), starts[i], float(radii[k + 1]) * factor) for i, k in np.argwhere(local)
    ]
    tried: list[float] = []
    for _, seed, radius in sorted(peaks, key=lambda peak: -peak[0]):
        if len(tried) == DISC_CANDIDATES:
            break
        if any(abs(radius - other) < 0.1 * other for other in tried):
            continue
        tried.append(radius)
        circle = _cutoff_edge(grey, seed, radius, half_px=DISC_GRID_HALF * short)
        for _ in range(CUTOFF_ITERATIONS):
            if circle is None:
                break
            found = _cutoff_edge(grey, circle.centre, circle.radius)
            moved = math.inf if found is None else math.dist(found.centre, circle.centre)
            circle = found
            if moved < 0.05:
                break
        if (
            circle is not None
            and circle.inliers >= DISC_MIN_FRACTION * RAYS
            and circle.rms_px <= MAX_CUTOFF_RMS_PX
            and math.dist(circle.centre, middle) <= DISC_MAX_OFFSET * short
            and DISC_RADII[0] * short < circle.radius < DISC_RADII[1] * short
        ):
            return circle
    return None


def _median_rise(image: NDArray[Any], centres: FloatArray, radii: FloatArray, rays: int) -> FloatArray:
    """The median over ``rays`` rays of the profiles' radial gradient (dark to bright going out, grey levels
    per px) about each of ``centres`` (n, 2) at ``radii`` (R,), smoothed over 5 samples: (n, R).

    :func:`_profiles` about every centre at once (one remap, one blur for all of them).
    """
    angles = np.linspace(0.0, 2 * math.pi, rays, endpoint=False)
    count = len(centres)
    map_u = (centres[:, 0, None, None] + np.cos(angles)[:, None] * radii[None, :]).astype(np.float32)
    map_v = (centres[:, 1, None, None] + np.sin(angles)[:, None] * radii[None, :]).astype(np.float32)
    map_u, map_v = map_u.reshape(count * rays, len(radii)), map_v.reshape(count * rays, len(radii))
    height, width = image.shape
    samples = cv2.remap(image, map_u, map_v, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=np.nan)
    samples[(map_u < 0) | (map_u > width - 1) | (map_v < 0) | (map_v > height - 1)] = np.nan
    samples = cv2.GaussianBlur(samples, (13, 1), PROFILE_SIGMA_PX / STEP, borderType=cv2.BORDER_REPLICATE)
    gradient = (np.gradient(samples, axis=1) / STEP).reshape(count, rays, len(radii))
    medians = _row_medians(gradient.transpose(0, 2, 1).reshape(count * len(radii), rays)).reshape(count, -1)
    padded = np.pad(np.nan_to_num(medians), ((0, 0), (2, 2)))
    return np.asarray(sum(padded[:, k : k + len(radii)] for k in range(5)) / 5, dtype=float)


def _cutoff_edge(grey: NDArray[Any], centre: tuple[float, float], radius: float, half_px: float = 0.0) -> Circle | None:
    """The circle through each ray's steepest dark-to-bright step within 5% (3 px, ``half_px`` at least) of
    ``radius`` about ``centre``; None where too few rays have one."""
    half = max(3.0, 0.05 * radius, half_px)
    margin = STEP * (EDGE_HALF_WINDOW + LEVEL_SAMPLES + 4)
    radii = np.arange(max(radius - half - margin, 1.0), radius + half + margin, STEP)
    samples, cos, sin = _profiles(grey, centre, radii)
    gradient = np.gradient(samples, axis=1) / STEP
    finite = np.isfinite(gradient)
    window = np.abs(radii - radius) <= half
    rising = np.where(window[None, :] & finite, gradient, -np.inf)
    best = np.clip(np.argmax(rising, axis=1), 1, len(radii) - 2)
    rows = np.arange(RAYS)
    before, after, in_frame = _step_levels(samples, best)
    good = in_frame & (gradient[rows, best] > 2.0) & (after - before > 8.0)
    if good.sum() < MIN_CUTOFF_FRACTION * RAYS:
        return None
    where = radii[0] + STEP * _subpixel_peak(np.where(finite, gradient, 0.0), best)
    r = where[good]
    points = np.stack([centre[0] + r * cos[good], centre[1] + r * sin[good]], axis=-1)
    try:
        return _robust_circle(points, centre, radius)
    except PanomapError:
        return None


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
        sigma = max(1.4826 * float(np.median(np.abs(r[inliers] - np.median(r[inliers])))), 0.1)
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


def draw_overlay(image: NDArray[Any], circles: ImageCircles) -> NDArray[Any]:
    """An 8-bit BGR copy of ``image`` with the found circles and centre drawn on it.

    The image circle is green, thicker on the arcs of the rim it was fitted to
    (the ellipse darker green, when there is one), the cut-off disc red, the
    centre a yellow cross; drawn with 1/16 px precision.
    """
    canvas, thickness = overlay_canvas(image)
    cv2.circle(
        canvas,
        at_subpixel(circles.outer.centre),
        round(circles.outer.radius * SUBPIXEL),
        (0, 220, 0),
        thickness,
        cv2.LINE_AA,
        SHIFT,
    )
    # The arcs the rim was fitted to, thicker.
    radius = round(circles.outer.radius * SUBPIXEL)
    for start, end in circles.rim_arcs_deg:
        cv2.ellipse(
            canvas,
            at_subpixel(circles.outer.centre),
            (radius, radius),
            0,
            start,
            end,
            (0, 255, 0),
            3 * thickness,
            cv2.LINE_AA,
            SHIFT,
        )
    if circles.ellipse is not None:
        e = circles.ellipse
        axes = (round(e.semi_axes[0] * SUBPIXEL), round(e.semi_axes[1] * SUBPIXEL))
        cv2.ellipse(
            canvas, at_subpixel(e.centre), axes, e.angle_deg, 0, 360, (0, 160, 0), thickness, cv2.LINE_AA, SHIFT
        )
    _draw_disc_and_cross(canvas, circles.cutoff, circles.centre, thickness)
    return canvas


def draw_no_rim_overlay(image: NDArray[Any], missing: NoImageCircle) -> NDArray[Any]:
    """An 8-bit BGR copy of ``image`` with what was found where no rim is: the cut-off disc in red (a
    mirror image that overfills the frame), when there is one, and the starting value for the centre (the
    disc's centre, else the frame's middle) a yellow cross; drawn as :func:`draw_overlay` draws them."""
    canvas, thickness = overlay_canvas(image)
    start = missing.frame_centre if missing.cutoff is None else missing.cutoff.centre
    _draw_disc_and_cross(canvas, missing.cutoff, start, thickness)
    return canvas


SHIFT = 4  # fractional bits of the drawn coordinates: 1/16 px
SUBPIXEL = 1 << SHIFT


def at_subpixel(point: tuple[float, float]) -> tuple[int, int]:
    """A point (px) in the fixed-point coordinates OpenCV draws with at ``shift=SHIFT``."""
    return round(point[0] * SUBPIXEL), round(point[1] * SUBPIXEL)


def overlay_canvas(image: NDArray[Any]) -> tuple[NDArray[Any], int]:
    """An 8-bit BGR copy of ``image`` to draw on, and the lines' thickness (px) for its size."""
    grey_or_colour = image if image.dtype == np.uint8 else (image / 257).astype(np.uint8)
    if grey_or_colour.ndim == 2 or grey_or_colour.shape[2] == 1:
        canvas = cv2.cvtColor(grey_or_colour.reshape(image.shape[:2]), cv2.COLOR_GRAY2BGR)
    else:
        canvas = np.array(grey_or_colour[..., :3])
    return canvas, max(1, round(min(image.shape[:2]) / 500))


def _draw_disc_and_cross(
    canvas: NDArray[Any], disc: Circle | None, centre: tuple[float, float], thickness: int
) -> None:
    """The cut-off disc (red), when given, and a yellow cross at ``centre``, drawn on ``canvas``."""
    if disc is not None:
        cv2.circle(
            canvas, at_subpixel(disc.centre), round(disc.radius * SUBPIXEL), (0, 0, 230), thickness, cv2.LINE_AA, SHIFT
        )
    size = 12 * thickness
    u, v = centre
    cv2.line(
        canvas, at_subpixel((u - size, v)), at_subpixel((u + size, v)), (0, 230, 230), thickness, cv2.LINE_AA, SHIFT
    )
    cv2.line(
        canvas, at_subpixel((u, v - size)), at_subpixel((u, v + size)), (0, 230, 230), thickness, cv2.LINE_AA, SHIFT
    )
