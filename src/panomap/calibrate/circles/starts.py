"""The three starts of the rim search: circles voted by the gradient (a circle transform), the coarse
blob's outline, and the concentric search about a centre.
"""

from __future__ import annotations

import math
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from ...errors import PanomapError
from ...geometry import FloatArray
from ...robust import mad_sigma
from .fitting import _algebraic_circle, _consensus_circle
from .frame import _quadrants
from .sampling import _edge_strength, _full_resolution, _profiles
from .thresholds import (
    COARSE_SIDE,
    CONCENTRIC_BACKGROUND_PX,
    CONCENTRIC_GRIDS,
    CONCENTRIC_LEAST_IN_FRAME,
    CONCENTRIC_PEAK_RATIO,
    CONCENTRIC_PROMINENCE,
    CONCENTRIC_RAYS,
    CONCENTRIC_SHARE,
    FEATURE_MIN_STRENGTH,
    LEVEL_FRACTIONS,
    LEVEL_ROUND_FRACTION,
    MIN_RIM_FRACTION,
    NEAR_PX,
    NESTED_FLOOR_LEVELS,
    NESTED_FLOOR_SPREAD,
    RAYS,
    STEP,
    VOTING_EDGES,
    VOTING_MIN_GRADIENT,
)


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
        # A disc covering under 40% of the frame (a small circle in a wide black frame): the bright
        # level is taken from the pixels clearly over the border's.
        lit = small[small > dark + 10]
        if lit.size < 0.05 * small.size:
            raise PanomapError("no image circle found: the image has no dark border around a brighter disc")
        bright = float(np.percentile(lit, 60))
    return [_blob_circle(_largest_blob(small, dark + 0.25 * (bright - dark)), small.shape, factor)]


def _level_circles(small: NDArray[Any], factor: int) -> list[tuple[tuple[float, float], float]]:
    """Circles (full-resolution px) of the round blobs of ``small`` over each of LEVEL_FRACTIONS of the way from
    its dark end (2nd percentile) to its bright one (99th), largest first; an error where there are none.

    The largest bright blob over one threshold (:func:`_coarse_circle`) is the disc only where the disc is the
    brightest thing: in a dark square inside a black frame it is the square; with a soft rim, a lens hood's
    ring or a glow about it, it takes in part of what lies past the rim. Over a higher level, the blob is the
    picture itself; where its outline away from the frame's edges lies on a circle (RMS under
    LEVEL_ROUND_FRACTION of its radius), that circle is a start: a level line of a soft rim is round, of a
    square or a scene it is not.
    """
    dark, bright = (float(level) for level in np.percentile(small, (2, 99)))
    found: list[tuple[tuple[float, float], float]] = []
    for fraction in LEVEL_FRACTIONS:
        try:
            contour = _largest_blob(small, dark + fraction * (bright - dark))
        except PanomapError:
            continue
        if not _round_blob(contour, small.shape, LEVEL_ROUND_FRACTION):
            continue
        try:
            centre, radius = _blob_circle(contour, small.shape, factor)
        except PanomapError:
            continue
        if not any(math.dist(centre, c) < NEAR_PX * factor and abs(radius - r) < NEAR_PX * factor for c, r in found):
            found.append((centre, radius))
    if not found:
        raise PanomapError("no image circle found: no level of the picture outlines a round disc")
    return sorted(found, key=lambda circle: -circle[1])


def _surround_floor(small: NDArray[Any]) -> float | None:
    """The level of a dark (not black) surround within the frame's black, or None where there is none.

    A robot's or tracking camera's fisheye may show its circle in a dark square (the sensor's
    pedestal, the lens's flare: 10-40 grey levels) inside a black frame: the largest bright blob
    of :func:`_coarse_circle` is then the square, and the rim steps down only to the square's level.
    That blob's margin (a band 4 px wide just inside its outline, in the downscaled image) lies
    NESTED_FLOOR_LEVELS or more over the frame's, with a brighter picture (the blob's 60th percentile
    10 levels more) over it; the floor returned is the band's median plus 3 robust sigmas (its noise).
    """
    dark, bright = (float(level) for level in np.percentile(small, (2, 60)))
    if bright - dark < 10:
        return None
    try:
        contour = _largest_blob(small, dark + 0.25 * (bright - dark))
    except PanomapError:
        return None
    inside = np.zeros(small.shape, np.uint8)
    cv2.drawContours(inside, [contour], -1, 1, thickness=-1)
    # The surround's level: a band just inside the blob's outline (the square's own margin), where the
    # disc may touch it too: the median of its darker half and that half's spread.
    band = (inside > 0) & (cv2.erode(inside, np.ones((9, 9), np.uint8)) == 0)
    band[:2], band[-2:], band[:, :2], band[:, -2:] = False, False, False, False
    if band.sum() < 50 or _round_blob(contour, small.shape):
        return None  # (a disc's own margin, darkened by vignetting, is no surround)
    values = small[band]
    darker = values[values <= np.median(values)]
    level = float(np.median(darker))
    spread = mad_sigma(darker, centre=level)
    lit = float(np.percentile(small[inside > 0], 60))
    floor = level + 3 * spread + 1
    flat = spread <= NESTED_FLOOR_SPREAD  # a pedestal, not a textured picture
    return floor if flat and level - dark >= NESTED_FLOOR_LEVELS and lit - floor >= 10 else None


def _round_blob(contour: NDArray[Any], shape: tuple[int, ...], fraction: float = 0.02) -> bool:
    """Whether a blob's outline away from the frame's edges lies on a circle (RMS under ``fraction`` of its
    radius)."""
    points = contour.reshape(-1, 2).astype(np.float64)
    height, width = shape[:2]
    off = (points[:, 0] > 1) & (points[:, 1] > 1) & (points[:, 0] < width - 2) & (points[:, 1] < height - 2)
    if off.sum() < 20:
        return False
    (cu, cv), radius = _algebraic_circle(points[off])
    distance = np.hypot(points[off, 0] - cu, points[off, 1] - cv) - radius
    return bool(np.sqrt(np.mean(distance**2)) < fraction * radius)


def _largest_blob(small: NDArray[Any], threshold: float) -> NDArray[Any]:
    """The outline (n, 1, 2) of the largest blob of ``small`` over ``threshold``, opened by 3 x 3; an error where
    none covers 5% of the image."""
    mask: NDArray[Any] = (small > threshold).astype(np.uint8)
    mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    if not contours:
        raise PanomapError("no image circle found: nothing stands out from the border")
    contour = max(contours, key=cv2.contourArea)
    if cv2.contourArea(contour) < 0.05 * small.size:
        raise PanomapError("no image circle found: the largest bright region is too small")
    return np.asarray(contour)


def _blob_circle(contour: NDArray[Any], shape: tuple[int, ...], factor: int) -> tuple[tuple[float, float], float]:
    """The circle (full-resolution px) through a blob's outline where it meets its convex hull, away from the
    frame's edges (of a downscaled image of ``shape``, shrunk by ``factor``)."""
    points = contour.reshape(-1, 2).astype(np.float64)
    height, width = shape[:2]
    on_border = (points[:, 0] <= 1) | (points[:, 1] <= 1) | (points[:, 0] >= width - 2) | (points[:, 1] >= height - 2)
    if np.sum(~on_border) < 0.3 * len(points) and _quadrants(points[~on_border], (height, width)) < 3:
        # (A round image just past the frame's sides still shows its rim about three or four corners.)
        raise PanomapError("no image circle found: the bright region fills the frame (no rim around it)")
    # Dark scene touching the rim dents the blob; the outline where it meets its convex hull is the rim.
    hull = cv2.convexHull(contour)
    on_hull = np.array([abs(cv2.pointPolygonTest(hull, (float(u), float(v)), True)) < 1.5 for u, v in points])
    arcs = points[on_hull & ~on_border]
    if len(arcs) < 20:
        arcs = points[~on_border]
    (cu, cv), radius = _algebraic_circle(arcs)
    return _full_resolution((cu, cv), factor), radius * factor
