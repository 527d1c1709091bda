"""What a real lens, sensor and housing do to a rendered omni-image: vignetting (to near black at the rim), a
dim side, a bright housing around a mirror with a camera board in it, a rim off the optical axis, a dark
square about the circle inside a black frame, a lens barrel's lit ring and a glow past the rim on one side, a halo
of scattered light about a bright rim, over-exposure, noise, JPEG.

Convention: pixel (u, v), u the column, v the row, the centre of the top-left pixel at
(0, 0); images are (H, W[, C]) uint8.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numpy.typing import NDArray

from ..errors import PanomapError


def vignette(
    image: NDArray[np.uint8],
    centre: tuple[float, float],
    radius: float,
    falloff: float = 0.5,
    dim: float = 0.0,
    dim_angle: float = 0.0,
    power: float = 2.0,
) -> NDArray[np.uint8]:
    """Darken an image towards the rim of its image circle, more on one side.

    The gain at distance ``r`` from ``centre`` and image angle ``phi`` is
    ``1 - falloff*(r/radius)**power - dim*max(0, cos(phi - dim_angle))*(r/radius)**power``:
    at the rim, ``1 - falloff`` all round and ``1 - falloff - dim`` on the dim side. A lens whose
    picture darkens to near black before its edge (a tracking camera's fisheye): ``falloff`` near 1,
    ``power`` 4-6 (the middle barely dimmed, the last tenth of the radius falling steeply).

    Parameters
    ----------
    image : (H, W[, C]) uint8 ndarray
    centre : (u, v), px
        Centre of the image circle.
    radius : float
        Its radius (px), > 0.
    falloff : float
        Darkening at the rim all round, in [0, 1).
    dim : float
        Extra darkening at the rim on the side ``dim_angle`` (rad), with
        ``falloff + dim < 1``.
    power : float
        Exponent of ``r/radius`` in the gain, > 0 (2: the cos^4 law's first term).

    Returns
    -------
    (H, W[, C]) uint8 ndarray
    """
    if not (radius > 0 and 0 <= falloff and 0 <= dim and falloff + dim < 1 and power > 0):
        raise PanomapError(
            f"need radius > 0, falloff, dim >= 0, falloff + dim < 1 and power > 0; "
            f"got {radius}, {falloff}, {dim}, {power}"
        )
    height, width = image.shape[:2]
    v, u = np.mgrid[0:height, 0:width].astype(np.float64)
    du, dv = u - centre[0], v - centre[1]
    reach = ((du**2 + dv**2) / radius**2) ** (power / 2)
    side = np.maximum(0.0, np.cos(np.arctan2(dv, du) - dim_angle))
    gain = np.clip(1.0 - falloff * reach - dim * side * reach, 0.0, 1.0)
    if image.ndim == 3:
        gain = gain[..., None]
    return np.clip(np.rint(image * gain), 0, 255).astype(np.uint8)


def field_stop(
    image: NDArray[np.uint8], centre: tuple[float, float], radius: float, softness_px: float = 0.0
) -> NDArray[np.uint8]:
    """Black outside a circle: a lens's field stop or a mirror's rim, which need not be centred on the optical axis.

    On real cameras the visible rim is 0.5-3 px off the optical axis (a mirror glued a little off
    centre, a lens's stop not quite on its axis). Render the camera with an image circle a little
    larger than ``radius`` plus the offset, then stop it down here about the rim's own ``centre``:
    each pixel keeps its exact coverage by the disc (pixel ``(u, v)`` covers
    ``[u - 0.5, u + 0.5] x [v - 0.5, v + 0.5]``; to within a hundredth of a pixel's area).

    Parameters
    ----------
    image : (H, W[, C]) uint8 ndarray
    centre : (u, v), px
        Centre of the rim.
    radius : float
        Its radius (px), > 0.
    softness_px : float
        A stop out of focus (a fisheye's field stop lies off the sensor's plane): the edge blurred
        by a Gaussian of this sigma (px), its half-level still at ``radius``; 0 (default): sharp.

    Returns
    -------
    (H, W[, C]) uint8 ndarray
    """
    if not (math.isfinite(radius) and radius > 0 and math.isfinite(softness_px) and softness_px >= 0):
        raise PanomapError(f"need a finite radius > 0 and softness >= 0, got {radius}, {softness_px}")
    height, width = image.shape[:2]
    v, u = np.mgrid[0:height, 0:width].astype(np.float64)
    r = np.hypot(u - centre[0], v - centre[1])
    if softness_px > 0:
        from scipy import special  # here, not at the top: importing SciPy is slow

        coverage = 0.5 * special.erfc((r - radius) / (math.sqrt(2.0) * softness_px))
    else:
        coverage = np.clip(radius - r + 0.5, 0.0, 1.0)  # the disc's share of each pixel, exact for a straight edge
    if image.ndim == 3:
        coverage = coverage[..., None]
    return np.clip(np.rint(image * coverage), 0, 255).astype(np.uint8)


def dark_square(
    image: NDArray[np.uint8],
    centre: tuple[float, float],
    radius: float,
    half_side_px: float,
    level: float = 30.0,
    square_centre: tuple[float, float] | None = None,
    glow: float = 0.0,
    under_disc: bool = False,
) -> NDArray[np.uint8]:
    """The image circle in a dark (not black) square, inside a black frame: a robot's or a tracking camera's
    fisheye, whose sensor reads a pedestal (and the lens's flare) outside the circle, its picture then
    placed in a larger black frame.

    Outside the disc of ``radius`` about ``centre`` (the render's black, which must be there), the square of
    half-side ``half_side_px`` about ``square_centre`` (default ``centre``) gets ``level`` grey levels, plus
    a glow of ``glow`` levels at the rim that fades over a tenth of the radius; the frame past the square stays
    black. The rim thus steps from the picture down to ``level``, and the square's edge from ``level`` to 0:
    two nested edges, the outer one straight (and the square may be cut by the frame). Disc and square are
    drawn with their exact coverage of each pixel. With ``under_disc``, the square's level (and the glow, fading
    either way from the rim) is added under the picture too, as a sensor's pedestal is: a soft rim (a stop
    out of focus, a picture vignetted to near black) then falls smoothly to the square's level, with no step
    at ``radius`` of the square's own drawing.

    Parameters
    ----------
    image : (H, W[, C]) uint8 ndarray
        A render (black outside its circle).
    centre : (u, v), px
        Centre of the image circle.
    radius, half_side_px : float
        The circle's radius and the square's half-side (px), ``0 < radius``, ``half_side_px > 0``.
    level, glow : float
        Grey levels of the square and of the glow at the rim, each in ``[0, 255]``.
    square_centre : (u, v), px, optional
    under_disc : bool
        Add the square's level under the disc too (default False: the disc's pixels untouched).

    Returns
    -------
    (H, W[, C]) uint8 ndarray
    """
    if not (radius > 0 and half_side_px > 0 and 0 <= level <= 255 and 0 <= glow <= 255):
        raise PanomapError(
            f"need radius, half_side_px > 0 and level, glow in [0, 255]; got {radius}, {half_side_px}, {level}, {glow}"
        )
    height, width = image.shape[:2]
    v, u = np.mgrid[0:height, 0:width].astype(np.float64)
    r = np.hypot(u - centre[0], v - centre[1])
    middle = centre if square_centre is None else square_centre
    chebyshev = np.maximum(np.abs(u - middle[0]), np.abs(v - middle[1]))
    square = np.clip(half_side_px - chebyshev + 0.5, 0.0, 1.0)
    outside = np.ones_like(r) if under_disc else np.clip(r - radius + 0.5, 0.0, 1.0)
    beyond = np.abs(r - radius) if under_disc else np.maximum(r - radius, 0.0)
    fill = square * outside * (level + glow * np.exp(-beyond / (0.1 * radius)))
    if image.ndim == 3:
        fill = fill[..., None]
    return np.clip(np.rint(image + fill), 0, 255).astype(np.uint8)


def _one_sided(
    shape: tuple[int, ...], centre: tuple[float, float], angle: float, spread: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Each pixel's distance (px) from ``centre`` and a weight over its image angle about it: 1 towards
    ``angle`` (rad), falling to 0 ``spread`` rad either side. Both ``shape[:2]``."""
    v, u = np.mgrid[0 : shape[0], 0 : shape[1]].astype(np.float64)
    phi = np.arctan2(v - centre[1], u - centre[0])
    off = np.abs((phi - angle + math.pi) % (2 * math.pi) - math.pi)
    return np.hypot(u - centre[0], v - centre[1]), np.clip(1.0 - off / spread, 0.0, 1.0)


def _added(image: NDArray[np.uint8], add: NDArray[np.float64]) -> NDArray[np.uint8]:
    """``image`` plus ``add`` grey levels (``image.shape[:2]``, on every channel), rounded and clipped."""
    return np.clip(np.rint(image + (add[..., None] if image.ndim == 3 else add)), 0, 255).astype(np.uint8)


def lit_ring(
    image: NDArray[np.uint8],
    centre: tuple[float, float],
    radius: float,
    level: float,
    at_px: float,
    width_px: float = 1.5,
    angle: float = 0.0,
    spread: float = math.pi / 2,
) -> NDArray[np.uint8]:
    """A lens barrel's edge lit past the rim, on part of the circle (a Ricoh Theta's bluish ring, an OCam's).

    Adds ``level`` grey levels times a Gaussian of sigma ``width_px`` (px) about the radius ``radius + at_px``
    around ``centre``, weighted 1 towards image angle ``angle`` (rad) and falling linearly to 0 ``spread`` rad
    either side: the ring shows on one arc, not all round. ``level``, ``at_px``, ``width_px``, ``spread`` > 0.
    """
    if not (radius > 0 and level >= 0 and at_px > 0 and width_px > 0 and spread > 0):
        raise PanomapError(
            f"need radius, at_px, width_px, spread > 0 and level >= 0; got {radius}, {at_px}, {width_px}"
        )
    r, weight = _one_sided(image.shape, centre, angle, spread)
    return _added(image, level * weight * np.exp(-0.5 * ((r - radius - at_px) / width_px) ** 2))


def side_glow(
    image: NDArray[np.uint8],
    centre: tuple[float, float],
    radius: float,
    level: float,
    fade_px: float,
    angle: float = 0.0,
    spread: float = math.pi / 2,
) -> NDArray[np.uint8]:
    """Light scattered past the rim on one side (flare from a bright scene near the rim, as on an OCam's picture).

    Outside ``radius`` about ``centre``, adds ``level`` grey levels fading as ``exp(-(r - radius) / fade_px)``,
    weighted as :func:`lit_ring` is by ``angle`` and ``spread`` (rad). ``level`` >= 0; ``fade_px``, ``spread`` > 0.
    """
    if not (radius > 0 and level >= 0 and fade_px > 0 and spread > 0):
        raise PanomapError(f"need radius, fade_px, spread > 0 and level >= 0; got {radius}, {level}, {fade_px}")
    r, weight = _one_sided(image.shape, centre, angle, spread)
    fade = np.exp(-np.maximum(r - radius, 0.0) / fade_px) * np.clip(r - radius + 0.5, 0.0, 1.0)
    return _added(image, level * weight * fade)


def halo(
    image: NDArray[np.uint8], centre: tuple[float, float], fraction: float, blur_px: float, angle: float, spread: float
) -> NDArray[np.uint8]:
    """Light scattered about a bright rim on one side (a real fisheye's halo where an over-exposed scene meets its
    rim, as on an OCam fisheye's picture): ``fraction`` of the picture itself blurred by a Gaussian of ``blur_px``
    (px) added, weighted as :func:`lit_ring` is by ``angle`` and ``spread`` (rad) about ``centre``.

    Unlike :func:`side_glow` (added past the rim only, from its edge on), the halo is smooth across the rim: the
    picture's light spread both ways, as a lens's scatter spreads it. ``fraction`` >= 0; ``blur_px``, ``spread``
    > 0.
    """
    if not (fraction >= 0 and blur_px > 0 and spread > 0):
        raise PanomapError(f"need fraction >= 0 and blur_px, spread > 0; got {fraction}, {blur_px}, {spread}")
    _, weight = _one_sided(image.shape, centre, angle, spread)
    spread_light = cv2.GaussianBlur(image.astype(np.float64), (0, 0), blur_px)
    if image.ndim == 3:
        weight = weight[..., None]
    return np.clip(np.rint(image + fraction * weight * spread_light), 0, 255).astype(np.uint8)


def over_exposed(image: NDArray[np.uint8], gain: float) -> NDArray[np.uint8]:
    """Every level times ``gain`` (> 0), clipped at 255: a sensor over-exposed after the lens's field stop, so a
    bright scene clips on the stop's blurred fall and its visible edge lies further out there than where the
    scene is dim."""
    if not (gain > 0 and math.isfinite(gain)):
        raise PanomapError(f"need a finite gain > 0, got {gain}")
    return np.clip(np.rint(image * gain), 0, 255).astype(np.uint8)


def noisy_jpeg(
    image: NDArray[np.uint8], rng: np.random.Generator, noise: float = 5.0, quality: int = 75
) -> NDArray[np.uint8]:
    """Gaussian noise of ``noise`` grey levels, then JPEG at ``quality``, decoded again."""
    if not (noise >= 0 and math.isfinite(noise) and 1 <= quality <= 100):
        raise PanomapError(f"need noise >= 0 and quality in 1..100; got {noise}, {quality}")
    noisy = np.clip(image + rng.normal(0.0, noise, image.shape), 0, 255).astype(np.uint8)
    ok, encoded = cv2.imencode(".jpg", noisy, [cv2.IMWRITE_JPEG_QUALITY, quality])
    if not ok:
        raise PanomapError("could not encode the JPEG")
    return np.asarray(cv2.imdecode(encoded, cv2.IMREAD_UNCHANGED), dtype=np.uint8)


def housed_mirror(
    image: NDArray[np.uint8],
    centre: tuple[float, float],
    outer_radius: float,
    cutoff_radius: float,
    rng: np.random.Generator,
    arcs: int = 6,
    faint: float = 0.0,
    lens_centre: tuple[float, float] | None = None,
) -> NDArray[np.uint8]:
    """A mirror camera as it is built: the mirror in a bright, blurred housing, and a camera board in the middle.

    What a small catadioptric camera shows (the mirror sits in a shiny tube that fills the
    frame, out of focus): outside ``outer_radius`` the frame is a bright housing, blurred
    (sigma 6 px), with concentric rings. Around the rim, ``arcs`` arcs of random lengths
    alternate between three kinds, drawn at random: a step (the housing 40-80 grey levels
    brighter than the mirror just inside it: darker inside), and a thin bright or dark line
    (2 px wide, 50-80 grey levels off) on a housing about as bright as the mirror just
    inside, so that the level barely steps there. The rim contrast thus changes sign
    around the circle. Inside ``cutoff_radius`` the camera sees itself: a square dark
    board (half-side 1.6-2 times the cut-off radius, turned at random, with lighter
    components on it) and in its middle a round lens of radius ``cutoff_radius``, darker
    still. The rim stays at ``outer_radius`` and the lens's edge at ``cutoff_radius``:
    every shape is drawn with its exact coverage of each pixel, and the mirror's picture,
    which ends at the rim with an edge of its own, is carried up to it at its level just
    inside (else the two edges would leave a dark band under the housing's). With ``faint``, one arc of
    that fraction of the rim (at a random angle) shows neither step nor line: the housing
    there is as bright as the mirror just inside, as on a real camera whose rim is seen
    only where the housing's light happens to differ.

    Parameters
    ----------
    image : (H, W, 3) uint8 ndarray
        A render of a mirror camera (:func:`panomap.simulate.render`).
    centre : (u, v), px
        Centre of the image circle and of the lens.
    outer_radius, cutoff_radius : float
        Radii (px) of the rim and of the lens, ``0 < cutoff_radius < outer_radius / 3``.
    rng : numpy.random.Generator
        Draws the arcs, the levels, the board's angle and its components.
    arcs : int
        Arcs around the rim, >= 3.
    faint : float
        Fraction of the rim, in ``[0, 1)``, on which the rim has no contrast (0: none).
    lens_centre : (u, v), px, optional
        Centre of the camera board and lens (the optical axis, about which the camera
        sees itself), where the rim is off it; default ``centre``.

    Returns
    -------
    (H, W, 3) uint8 ndarray
    """
    if not (0 < cutoff_radius < outer_radius / 3 and arcs >= 3 and 0 <= faint < 1):
        raise PanomapError(
            f"need 0 < cutoff_radius < outer_radius / 3, arcs >= 3 and 0 <= faint < 1; "
            f"got {cutoff_radius}, {outer_radius}, {arcs}, {faint}"
        )
    height, width = image.shape[:2]
    v, u = np.mgrid[0:height, 0:width].astype(np.float64)
    du, dv = u - centre[0], v - centre[1]
    r = np.hypot(du, dv)
    phi = np.arctan2(dv, du) % (2 * math.pi)
    grey = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY).astype(np.float64)

    # The arcs: their starts (rad), kinds (0 step, +1 bright line, -1 dark line), and levels.
    starts = np.sort(rng.uniform(0, 2 * math.pi, arcs))
    kinds = rng.permutation(np.resize(np.array([0, 1, -1]), arcs))
    arc_of = (np.searchsorted(starts, phi, side="right") - 1) % arcs
    # The mirror's level just inside the rim, per degree of image angle (smoothed along the rim).
    ring = (r > outer_radius - 10) & (r < outer_radius - 3)
    degree = np.floor(np.degrees(phi[ring])).astype(np.int64) % 360
    total = np.bincount(degree, weights=grey[ring], minlength=360)
    count = np.bincount(degree, minlength=360)
    inside_level = np.where(count > 0, total / np.maximum(count, 1), np.nan)
    # (Where the frame shows none of the rim, the housing lies wholly outside it: any level will do.)
    fallback = float(np.nanmedian(inside_level)) if np.isfinite(inside_level).any() else float(np.median(grey))
    inside_level = np.where(np.isfinite(inside_level), inside_level, fallback)
    inside_level = np.convolve(np.tile(inside_level, 3), np.ones(15) / 15, mode="same")[360:720]
    offsets = np.where(kinds == 0, rng.uniform(40, 80, arcs), rng.uniform(-5, 5, arcs))
    lines = np.where(kinds == 0, 0.0, kinds * rng.uniform(50, 80, arcs))
    # The housing: the mirror's level plus the arc's offset, concentric rings, then blurred.
    rings = 15.0 * np.sin(2 * math.pi * r / rng.uniform(25, 45) + rng.uniform(0, 2 * math.pi))
    offset, line = offsets[arc_of], lines[arc_of]
    if faint > 0:
        start = rng.uniform(0, 2 * math.pi)
        on_faint = (phi - start) % (2 * math.pi) < 2 * math.pi * faint
        offset, line = np.where(on_faint, 0.0, offset), np.where(on_faint, 0.0, line)
    level_here = inside_level[np.floor(np.degrees(phi)).astype(np.int64) % 360]
    housing = level_here + offset + rings
    housing = cv2.GaussianBlur(housing, (0, 0), 6.0)
    outside = np.clip(r - outer_radius + 0.5, 0.0, 1.0)  # coverage of each pixel by the housing
    # The render's own edge at the rim (black beyond it) must not show under the housing's:
    # on the rim's pixels the mirror is carried out at its level just inside.
    mirror = np.where(r > outer_radius - 1.5, level_here, grey)
    result = mirror * (1 - outside) + housing * outside
    # A thin line (2 px) centred on the rim, on the line arcs: its coverage of each pixel.
    on_line = np.clip(1.0 - np.maximum(np.abs(r - outer_radius) - 0.5, 0.0), 0.0, 1.0)
    result += on_line * line

    # The camera board: a dark square with lighter components, and the lens in its middle.
    if lens_centre is not None:
        du, dv = u - lens_centre[0], v - lens_centre[1]
        r = np.hypot(du, dv)
    half_side = cutoff_radius * rng.uniform(1.6, 2.0)
    turn = rng.uniform(0, math.pi / 2)
    x = du * math.cos(turn) + dv * math.sin(turn)
    y = -du * math.sin(turn) + dv * math.cos(turn)
    board = np.clip(half_side - np.maximum(np.abs(x), np.abs(y)) + 0.5, 0.0, 1.0)
    board_level = np.full_like(grey, rng.uniform(55, 75))
    for _ in range(6):
        cx, cy = rng.uniform(-half_side, half_side, 2)
        size = rng.uniform(0.1, 0.25) * half_side
        part = (np.abs(x - cx) < size) & (np.abs(y - cy) < size) & (np.hypot(x, y) > cutoff_radius + 2)
        board_level[part] += rng.uniform(30, 60)
    result = result * (1 - board) + board_level * board
    lens = np.clip(cutoff_radius - r + 0.5, 0.0, 1.0)
    result = result * (1 - lens) + rng.uniform(15, 30) * lens
    out = np.clip(np.rint(result), 0, 255).astype(np.uint8)
    return cv2.cvtColor(out, cv2.COLOR_GRAY2BGR)
