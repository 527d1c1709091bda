"""Finding the image centre, the cut-off radius and the image circle in an omni-image.

Convention: pixel (u, v), u the column, v the row, the centre of the top-left
pixel at (0, 0); radii in px; image angle ``atan2(v - v0, u - u0)``.

Method (paper 2.1 and 3 find these automatically; refs. [18, 19] use circle
transforms):

1. **Start.** The image circle is the bright disc inside a dark border: a
   threshold of the smoothed, downscaled image, its largest blob with its holes
   filled, gives a first centre and radius (a circle transform, by moments).
2. **Rim edge points.** Along 720 rays from that centre, the intensity profile
   across the rim is sampled at full resolution (bilinear), smoothed, and the
   steepest bright-to-dark step is located to a fraction of a pixel.
3. **Robust circle fit.** A geometric least-squares circle with a soft-L1
   loss, then a refit on the inliers (points within 3 robust sigmas); steps 2-3
   repeat from the new centre. An ellipse is fitted to the same inliers and
   reported when the rim is measurably elliptical (non-square pixels, a tilted
   mirror); its centre is then the image centre.
4. **Cut-off disc.** From the centre, each ray's first dark-to-bright step
   inside the image circle, fitted the same way. A fisheye, whose centre sees
   the scene, has none; the disc is reported only when most rays agree on it.

Every failure is an error with a reason, never a guess.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from ..errors import PanomapError
from ..geometry import FloatArray, pixel_polar

RAYS = 720
COARSE_SIDE = 400
# Edge points further than this from the fitted circle (in robust sigmas) are outliers.
INLIER_SIGMAS = 3.0
MIN_RIM_FRACTION = 0.35
CONVINCING_RIM_FRACTION = 0.6
# Real rims fit to 0.2-0.9 px RMS; a false circle through scene edges fits worse.
MAX_RIM_RMS_PX = 1.5
MIN_CUTOFF_FRACTION = 0.6
# An ellipse is reported when its axes differ by more than this fraction and it fits clearly better.
ELLIPSE_MIN_ECCENTRICITY = 0.003


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
    """

    centre: tuple[float, float]
    outer: Circle
    cutoff: Circle | None
    ellipse: Ellipse | None

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
        }


def to_grey(image: NDArray[Any]) -> NDArray[Any]:
    """(H, W) float32 grey levels on a 0..255 scale, from 8- or 16-bit, 1, 3 or 4 channels."""
    scale = 255.0 / 65535.0 if image.dtype == np.uint16 else 1.0
    if image.ndim == 3 and image.shape[2] >= 3:
        grey = cv2.cvtColor(image[..., :3], cv2.COLOR_BGR2GRAY)
    else:
        grey = image.reshape(image.shape[0], image.shape[1])
    return grey.astype(np.float32) * np.float32(scale)


def find_image_circles(image: NDArray[Any]) -> ImageCircles:
    """Find the image centre, the image circle and the cut-off disc of an omni-image.

    Parameters
    ----------
    image : (H, W[, C]) ndarray
        8- or 16-bit omni-image, any channel count.

    Raises
    ------
    PanomapError
        When there is no image circle (an ordinary photo, a blank image).
    """
    grey = to_grey(image)
    height, width = grey.shape
    if min(height, width) < 32:
        raise PanomapError(f"the image is too small ({width} x {height}) to find an image circle in")
    smooth = cv2.GaussianBlur(grey, (0, 0), 1.0)
    reasons: list[str] = []
    best: tuple[Circle, FloatArray] | None = None
    # The dark-border blob first; the circle transform's candidates when it is not convincing.
    for stage in (_coarse_circle, _hough_circles):
        try:
            candidates = stage(grey)
        except PanomapError as exc:
            reasons.append(exc.detail)
            continue
        for centre, radius in candidates:
            try:
                found = _refine_rim(smooth, centre, radius)
            except PanomapError as exc:
                reasons.append(exc.detail)
                continue
            if best is None or found[0].inliers > best[0].inliers:
                best = found
        if best is not None and best[0].inliers >= CONVINCING_RIM_FRACTION * RAYS:
            break
    if best is None:
        raise PanomapError(reasons[0] if reasons else "no image circle found")
    outer, points = best
    centre = outer.centre
    ellipse = _ellipse(points, outer)
    if ellipse is not None:
        centre = ellipse.centre
    cutoff = _cutoff_circle(smooth, centre, outer.radius)
    return ImageCircles(centre=centre, outer=outer, cutoff=cutoff, ellipse=ellipse)


def _refine_rim(smooth: NDArray[Any], centre: tuple[float, float], radius: float) -> tuple[Circle, FloatArray]:
    """Rim edge points and the robust circle through them, iterated from a start circle."""
    circle = None
    for _ in range(3):
        points = _rim_points(smooth, centre, radius)
        if len(points) < MIN_RIM_FRACTION * RAYS:
            raise PanomapError(
                f"no image circle found: only {len(points)} of {RAYS} rays cross a bright-to-dark rim "
                "(is this an omni-image with a dark border?)"
            )
        circle = _robust_circle(points, centre, radius)
        moved = math.dist(circle.centre, centre)
        centre, radius = circle.centre, circle.radius
        if moved < 0.01:
            break
    assert circle is not None
    if circle.inliers < MIN_RIM_FRACTION * RAYS or (
        circle.rms_px > MAX_RIM_RMS_PX and _ellipse(points, circle) is None
    ):
        raise PanomapError(
            f"no image circle found: the rim's edge points do not lie on a circle "
            f"({circle.inliers} of {RAYS} agree, RMS {circle.rms_px:.2f} px)"
        )
    height, width = smooth.shape
    if circle.radius < 0.2 * min(height, width) or not (0 <= centre[0] < width and 0 <= centre[1] < height):
        raise PanomapError("no image circle found: the only circle is too small or off the image")
    return circle, points


def _hough_circles(grey: NDArray[Any], count: int = 3) -> list[tuple[tuple[float, float], float]]:
    """Up to ``count`` strongest large circles of a circle transform of the downscaled image."""
    height, width = grey.shape
    factor = max(1, math.ceil(max(height, width) / COARSE_SIDE))
    small = cv2.resize(grey, (width // factor, height // factor), interpolation=cv2.INTER_AREA)
    small8 = np.clip(cv2.GaussianBlur(small, (0, 0), 1.5), 0, 255).astype(np.uint8)
    side = min(small8.shape)
    found = cv2.HoughCircles(
        small8,
        cv2.HOUGH_GRADIENT,
        dp=1,
        minDist=side / 8,
        param1=60,
        param2=20,
        minRadius=int(0.2 * side),
        maxRadius=int(0.75 * max(small8.shape)),
    )
    if found is None:
        return []
    return [
        (((u + 0.5) * factor - 0.5, (v + 0.5) * factor - 0.5), r * factor)
        for u, v, r in found[0, :count].astype(np.float64)
    ]


def _coarse_circle(grey: NDArray[Any]) -> list[tuple[tuple[float, float], float]]:
    """First centre and radius (full-resolution px) from the largest bright blob of a downscaled image."""
    height, width = grey.shape
    factor = max(1, math.ceil(max(height, width) / COARSE_SIDE))
    small = cv2.resize(grey, (width // factor, height // factor), interpolation=cv2.INTER_AREA)
    small = cv2.GaussianBlur(small, (0, 0), 1.5)
    dark = float(np.percentile(small, 2))
    bright = float(np.percentile(small, 60))
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
    moments = cv2.moments(contour)
    if area < 0.05 * small.size or moments["m00"] <= 0:
        raise PanomapError("no image circle found: the largest bright region is too small")
    # Moments of the filled outline are those of the disc, holes and dark scene parts included.
    cu = moments["m10"] / moments["m00"]
    cv = moments["m01"] / moments["m00"]
    radius = math.sqrt(area / math.pi)
    touches = _touches_border(contour, small.shape)
    if touches > 0.5:
        raise PanomapError(
            "no image circle found: the bright region fills the frame (an ordinary photo, not an omni-image?)"
        )
    if touches > 0:
        # A circle cut by the frame: its moments are biased; the enclosing circle is a better start.
        (cu, cv), radius = cv2.minEnclosingCircle(contour)
    # Sample positions of the small image: pixel centres at (k + 0.5) * factor - 0.5.
    centre = ((cu + 0.5) * factor - 0.5, (cv + 0.5) * factor - 0.5)
    return [(centre, radius * factor)]


def _touches_border(contour: NDArray[Any], shape: tuple[int, ...]) -> float:
    """Fraction of the contour's points on the image border."""
    points = contour.reshape(-1, 2)
    height, width = shape[:2]
    on_border = (points[:, 0] <= 0) | (points[:, 1] <= 0) | (points[:, 0] >= width - 1) | (points[:, 1] >= height - 1)
    return float(np.mean(on_border))


def _profiles(
    grey: NDArray[Any], centre: tuple[float, float], radii: FloatArray
) -> tuple[NDArray[Any], FloatArray, FloatArray]:
    """Bilinear samples (RAYS, R) of ``grey`` along rays at ``radii``; NaN outside the image."""
    angles = np.linspace(0.0, 2 * math.pi, RAYS, endpoint=False)
    cos, sin = np.cos(angles), np.sin(angles)
    map_u = (centre[0] + cos[:, None] * radii[None, :]).astype(np.float32)
    map_v = (centre[1] + sin[:, None] * radii[None, :]).astype(np.float32)
    height, width = grey.shape
    samples = cv2.remap(grey, map_u, map_v, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=np.nan)
    inside = (map_u >= 0) & (map_u <= width - 1) & (map_v >= 0) & (map_v <= height - 1)
    return np.where(inside, samples, np.nan), cos, sin


def _subpixel_peak(values: NDArray[Any], index: NDArray[Any]) -> FloatArray:
    """Parabola vertex through samples index-1, index, index+1 of each row (index inside)."""
    rows = np.arange(values.shape[0])
    left, mid, right = values[rows, index - 1], values[rows, index], values[rows, index + 1]
    denominator = left - 2 * mid + right
    with np.errstate(divide="ignore", invalid="ignore"):
        offset = np.where(denominator != 0, 0.5 * (left - right) / denominator, 0.0)
    return index + np.clip(offset, -0.5, 0.5)


STEP = 0.5  # px between profile samples


def _rim_points(grey: NDArray[Any], centre: tuple[float, float], radius: float) -> FloatArray:
    """Sub-pixel rim edge points (n, 2): the steepest bright-to-dark step near ``radius``."""
    half = max(0.08 * radius, 8.0)
    radii = np.arange(max(radius - half, 1.0), radius + half, STEP)
    samples, cos, sin = _profiles(grey, centre, radii)
    gradient = np.gradient(samples, axis=1)
    usable = np.all(np.isfinite(samples), axis=1)
    gradient = np.where(np.isfinite(gradient), gradient, 0.0)
    index = np.clip(np.argmin(gradient[:, 1:-1], axis=1) + 1, 1, len(radii) - 2)
    rows = np.arange(RAYS)
    drop = -gradient[rows, index] / STEP
    position = np.arange(len(radii))[None, :]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # rays whose profile is all outside: NaN, dropped below
        outside = np.nanmedian(np.where(position > index[:, None] + 4, samples, np.nan), axis=1)
        inside = np.nanmedian(np.where(position < index[:, None] - 4, samples, np.nan), axis=1)
    step = inside - outside
    # A rim: a steep step down to something clearly darker.
    good = usable & (drop > 2.0) & (step > 8.0)
    where = radii[0] + STEP * _subpixel_peak(-gradient, index)
    r = where[good]
    return np.stack([centre[0] + r * cos[good], centre[1] + r * sin[good]], axis=-1)


def _cutoff_circle(grey: NDArray[Any], centre: tuple[float, float], outer_radius: float) -> Circle | None:
    """The self-occlusion disc: each ray's first dark-to-bright step; None when rays disagree."""
    radii = np.arange(1.0, 0.75 * outer_radius, STEP)
    samples, cos, sin = _profiles(grey, centre, radii)
    core = samples[:, radii < 4.0]
    dark_level = float(np.nanmedian(core)) if core.size else float("nan")
    content_level = float(np.nanmedian(samples))
    if not math.isfinite(dark_level) or content_level - dark_level < 15.0:
        return None
    level = dark_level + 0.5 * (content_level - dark_level)
    above = samples > level
    first = np.argmax(above, axis=1)
    has = above[np.arange(RAYS), first] & (first > 2)
    gradient = np.gradient(samples, axis=1)
    gradient = np.where(np.isfinite(gradient), gradient, 0.0)
    # The steepest rise within 3 px of the crossing.
    window = round(3.0 / STEP)
    offsets = np.arange(-window, window + 1)
    candidates = np.clip(first[:, None] + offsets[None, :], 1, len(radii) - 2)
    best = candidates[np.arange(RAYS), np.argmax(np.take_along_axis(gradient, candidates, axis=1), axis=1)]
    where = radii[0] + STEP * _subpixel_peak(gradient, best)
    good = has & np.all(np.isfinite(samples[:, : max(int(first.max()), 1)]), axis=1)
    if good.sum() < MIN_CUTOFF_FRACTION * RAYS:
        return None
    r = where[good]
    points = np.stack([centre[0] + r * cos[good], centre[1] + r * sin[good]], axis=-1)
    start = float(np.median(r))
    circle = _robust_circle(points, centre, start)
    agrees = math.dist(circle.centre, centre) < max(2.0, 0.05 * circle.radius)
    if circle.inliers < MIN_CUTOFF_FRACTION * RAYS or circle.rms_px > 1.5 or not agrees:
        return None
    return circle


def _robust_circle(points: FloatArray, centre: tuple[float, float], radius: float) -> Circle:
    """Geometric circle fit with a soft-L1 loss, then least squares on the inliers."""
    from scipy import optimize  # here, not at the top: importing SciPy is slow

    def residuals(p: FloatArray, xy: FloatArray) -> FloatArray:
        return np.hypot(xy[:, 0] - p[0], xy[:, 1] - p[1]) - p[2]

    start = np.array([centre[0], centre[1], radius], dtype=np.float64)
    robust = optimize.least_squares(residuals, start, loss="soft_l1", f_scale=0.5, args=(points,))
    r = residuals(robust.x, points)
    sigma = max(1.4826 * float(np.median(np.abs(r - np.median(r)))), 0.1)
    inliers = np.abs(r) < INLIER_SIGMAS * sigma
    if inliers.sum() < 3:
        raise PanomapError("no circle found: too few consistent edge points")
    final = optimize.least_squares(residuals, robust.x, args=(points[inliers],))
    if not final.success:
        raise PanomapError(f"the circle fit did not converge ({final.message})")
    r = residuals(final.x, points[inliers])
    return Circle(
        centre=(float(final.x[0]), float(final.x[1])),
        radius=float(final.x[2]),
        rms_px=float(np.sqrt(np.mean(r**2))),
        inliers=int(inliers.sum()),
        rays=RAYS,
    )


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

    The image circle is green (the ellipse too, when there is one), the cut-off
    disc red, the centre a yellow cross; drawn with 1/16 px precision.
    """
    grey_or_colour = image if image.dtype == np.uint8 else (image / 257).astype(np.uint8)
    if grey_or_colour.ndim == 2 or grey_or_colour.shape[2] == 1:
        canvas = cv2.cvtColor(grey_or_colour.reshape(image.shape[:2]), cv2.COLOR_GRAY2BGR)
    else:
        canvas = np.ascontiguousarray(grey_or_colour[..., :3])
    shift = 4
    scale = 1 << shift
    thickness = max(1, round(min(image.shape[:2]) / 500))

    def at(point: tuple[float, float]) -> tuple[int, int]:
        return round(point[0] * scale), round(point[1] * scale)

    cv2.circle(
        canvas,
        at(circles.outer.centre),
        round(circles.outer.radius * scale),
        (0, 220, 0),
        thickness,
        cv2.LINE_AA,
        shift,
    )
    if circles.ellipse is not None:
        e = circles.ellipse
        axes = (round(e.semi_axes[0] * scale), round(e.semi_axes[1] * scale))
        cv2.ellipse(canvas, at(e.centre), axes, e.angle_deg, 0, 360, (0, 160, 0), thickness, cv2.LINE_AA, shift)
    if circles.cutoff is not None:
        c = circles.cutoff
        cv2.circle(canvas, at(c.centre), round(c.radius * scale), (0, 0, 230), thickness, cv2.LINE_AA, shift)
    size = 12 * thickness
    u, v = circles.centre
    cv2.line(canvas, at((u - size, v)), at((u + size, v)), (0, 230, 230), thickness, cv2.LINE_AA, shift)
    cv2.line(canvas, at((u, v - size)), at((u, v + size)), (0, 230, 230), thickness, cv2.LINE_AA, shift)
    return canvas
