"""What was found, drawn on the omni-image: the circles (``panomap centre --overlay``) and the fit
(``panomap fit --overlay``): what a table says the camera sees, where.

:func:`draw_overlay` draws the circles found (:func:`panomap.calibrate.circles.find_image_circles`),
:func:`draw_no_rim_overlay` what was found where no rim is, and :func:`draw_fit_overlay` the fit, on
an 8-bit BGR copy of the image, with 1/16 px precision:

- the annulus the table covers, about the fitted centre: the image circle green, the
  cut-off disc red; the fitted centre a yellow cross, and where the fit started
  from (when it moved the centre) a grey one joined to it;
- circles of equal world elevation every 30 deg, the horizon (elevation 0) thick
  cyan, with their elevations written beside them: on a level camera they are
  concentric about the centre, on a tilted one they are not, and the horizon runs
  through the landmarks that are level with the camera;
- the world's azimuth 0 (+X) as a magenta ray from the centre;
- each landmark's pixel a circle, green, and the way to where the fit puts its
  world point a line, magnified by the factor the legend gives; the landmarks
  dropped as outliers red, at true scale, with their names.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from ..calibrate.circles import Circle, ImageCircles, NoImageCircle
from ..calibrate.core.report import FitReport, table_fit_report
from ..table.table import PanoMappingTable

SHIFT = 4  # fractional bits of the drawn coordinates: 1/16 px
SUBPIXEL = 1 << SHIFT
HORIZON = (230, 230, 0)  # BGR: cyan
ELEVATION_CIRCLE = (200, 160, 0)
AZIMUTH_ZERO = (230, 0, 230)  # magenta
INLIER = (0, 230, 0)
OUTLIER = (0, 0, 255)
OUTER = (0, 220, 0)
CUTOFF = (0, 0, 230)
CENTRE = (0, 230, 230)
CENTRE_START = (160, 160, 160)
ELEVATION_STEP_DEG = 30
CIRCLE_POINTS = 1440
# The residuals are drawn magnified by the largest of these for which the largest inlier's stays within
# RESIDUAL_SHARE of the image's short side: a residual of a pixel is invisible on a 2000 px image.
MAGNIFICATIONS = (1, 2, 5, 10, 20, 50, 100)
RESIDUAL_SHARE = 0.04


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


def draw_fit_overlay(image: NDArray[Any], table: PanoMappingTable) -> NDArray[np.uint8]:
    """An 8-bit BGR copy of ``image`` (H, W[, C], the omni-image the table was fitted on) with the table's
    annulus, centre, circles of equal world elevation, world azimuth 0 and landmark residuals drawn on it.

    Raises
    ------
    PanomapError
        If the table's fit report is malformed.
    """
    canvas, thickness = overlay_canvas(image)
    fit = table_fit_report(table)
    centre = table.model.centre
    _circle(canvas, centre, table.outer_radius, OUTER, thickness)
    if table.cutoff_radius > 0:
        _circle(canvas, centre, table.cutoff_radius, CUTOFF, thickness)
    _elevation_circles(canvas, table, thickness)
    _azimuth_zero(canvas, table, thickness)
    if fit is not None and fit.centre_start is not None and math.dist(fit.centre_start, centre) > 0.5:
        _cross(canvas, fit.centre_start, CENTRE_START, thickness)
        cv2.line(
            canvas, at_subpixel(fit.centre_start), at_subpixel(centre), CENTRE_START, thickness, cv2.LINE_AA, SHIFT
        )
    _cross(canvas, centre, CENTRE, thickness)
    magnification = 1
    if fit is not None:
        largest = max((row.residual_px for row in fit.landmarks if not row.outlier), default=0.0)
        magnification = residual_magnification(largest, min(canvas.shape[:2]))
        _landmarks(canvas, fit, magnification, thickness)
    _legend(canvas, table, fit, magnification, thickness)
    return canvas


def residual_magnification(largest_px: float, short_side_px: int) -> int:
    """How many times the inliers' residuals are drawn: the largest of MAGNIFICATIONS that keeps the largest
    inlier's (px) within RESIDUAL_SHARE of the image's short side (px)."""
    largest = largest_px
    room = RESIDUAL_SHARE * short_side_px
    fitting = [m for m in MAGNIFICATIONS if m * largest <= room]
    return fitting[-1] if fitting else 1


def _elevation_circles(canvas: NDArray[np.uint8], table: PanoMappingTable, thickness: int) -> None:
    """Curves of equal world elevation every ELEVATION_STEP_DEG within the table's range, the horizon thicker."""
    low, high = (math.degrees(rho) for rho in table.elevation_range)
    step = ELEVATION_STEP_DEG
    theta = np.linspace(0.0, 2 * math.pi, CIRCLE_POINTS, endpoint=False)
    label_theta = math.radians(-20.0)
    for elevation_deg in range(math.ceil(low / step) * step, math.floor(high / step) * step + 1, step):
        if abs(elevation_deg) >= 90:
            continue  # (a point: the nadir or the zenith)
        rho = np.full_like(theta, math.radians(elevation_deg))
        pixels = np.asarray(table.sample(theta, rho), dtype=np.float64)
        colour, width = (HORIZON, 2 * thickness) if elevation_deg == 0 else (ELEVATION_CIRCLE, thickness)
        for run in _finite_runs(pixels, closed=True):
            cv2.polylines(canvas, [_points(run)], False, colour, width, cv2.LINE_AA, SHIFT)
        where = np.asarray(table.sample(np.array([label_theta]), np.array([math.radians(elevation_deg)])))[0]
        if np.all(np.isfinite(where)):
            _text(canvas, f"{elevation_deg} deg", (float(where[0]), float(where[1])), colour, thickness)


def _azimuth_zero(canvas: NDArray[np.uint8], table: PanoMappingTable, thickness: int) -> None:
    """The world's azimuth 0 (+X) over the table's elevations, labelled at its outer end."""
    rho = np.linspace(*table.elevation_range, 256)
    pixels = np.asarray(table.sample(np.zeros_like(rho), rho), dtype=np.float64)
    runs = _finite_runs(pixels, closed=False)
    for run in runs:
        cv2.polylines(canvas, [_points(run)], False, AZIMUTH_ZERO, thickness, cv2.LINE_AA, SHIFT)
    if runs:
        end = runs[-1][-1]
        _text(canvas, "+X", (float(end[0]), float(end[1])), AZIMUTH_ZERO, thickness)


def _landmarks(canvas: NDArray[np.uint8], fit: FitReport, magnification: int, thickness: int) -> None:
    """Each landmark's pixel and the way to where the fit puts it (outliers red, at true scale, named)."""
    marker = 5 * thickness
    for row in sorted(fit.landmarks, key=lambda r: r.outlier):  # (outliers drawn last: on top)
        pixel = (row.u, row.v)
        colour = OUTLIER if row.outlier else INLIER
        scale = 1 if row.outlier else magnification
        if math.isfinite(row.u_fit) and math.isfinite(row.v_fit):
            end = (row.u + scale * (row.u_fit - row.u), row.v + scale * (row.v_fit - row.v))
            cv2.line(canvas, at_subpixel(pixel), at_subpixel(end), colour, thickness, cv2.LINE_AA, SHIFT)
        cv2.circle(canvas, at_subpixel(pixel), marker * SUBPIXEL, colour, thickness, cv2.LINE_AA, SHIFT)
        if row.outlier:
            label = f"{row.name} (outlier, {row.residual_px:.1f} px)"
            _text(canvas, label, (row.u + marker, row.v - marker), OUTLIER, thickness)


def _legend(
    canvas: NDArray[np.uint8], table: PanoMappingTable, fit: FitReport | None, magnification: int, thickness: int
) -> None:
    """What the colours are, the fit's figures and the magnification, at the top left."""
    lines = [f"model {table.model.radial.kind}; centre ({table.model.centre[0]:.2f}, {table.model.centre[1]:.2f})"]
    if fit is not None:
        inliers = sum(not row.outlier for row in fit.landmarks)
        lines.append(
            f"{inliers} landmarks (green): RMS {fit.rms_px:.2f} px, max {fit.max_px:.2f} px; "
            f"residuals drawn x{magnification}"
        )
        if fit.outliers:
            lines.append(f"outliers (red, true scale): {', '.join(fit.outliers)}")
        if fit.mount is not None and fit.mount.tilt_deg > 0:
            lines.append(f"tilt {fit.mount.tilt_deg:.2f} deg toward azimuth {fit.mount.toward_deg:.1f} deg")
    lines.append("cyan: horizon (elevation 0); blue: every 30 deg; magenta: azimuth 0 (+X)")
    draw_legend(canvas, lines, thickness)


# The legend's darkening of the picture behind it (the fraction of the picture kept).
LEGEND_SHADE = 0.3


def draw_legend(
    canvas: NDArray[np.uint8], lines: Sequence[str], thickness: int, colour: tuple[int, int, int] = (255, 255, 255)
) -> None:
    """``lines`` at the top left, each wrapped to the picture's width, on a dark box (plain text on it: an
    outline drawn around small letters fills the gaps between them), one text height apart."""
    scale = 0.4 * thickness
    room = max(canvas.shape[1] - 24, 40)
    wrapped = [part for line in lines for part in _wrapped(line, scale, thickness, room)]
    (_, height), baseline = cv2.getTextSize("Ag", cv2.FONT_HERSHEY_SIMPLEX, scale, thickness)
    step = height + baseline + thickness
    widest = max(cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, scale, thickness)[0][0] for text in wrapped)
    right, bottom = min(canvas.shape[1], 16 + widest), min(canvas.shape[0], 8 + step * len(wrapped) + 2 * thickness)
    canvas[:bottom, :right] = (canvas[:bottom, :right] * LEGEND_SHADE).astype(np.uint8)
    for k, text in enumerate(wrapped):
        at = (8, 6 + height + step * k)
        cv2.putText(canvas, text, at, cv2.FONT_HERSHEY_SIMPLEX, scale, colour, thickness, cv2.LINE_AA)


def _wrapped(text: str, scale: float, thickness: int, width: int) -> list[str]:
    """``text`` cut between words into lines at most ``width`` px wide (a word wider than that on its own)."""
    out: list[str] = []
    for word in text.split(" "):
        joined = f"{out[-1]} {word}" if out else word
        if out and cv2.getTextSize(joined, cv2.FONT_HERSHEY_SIMPLEX, scale, thickness)[0][0] <= width:
            out[-1] = joined
        else:
            out.append(word)
    return out


def _finite_runs(pixels: NDArray[np.float64], closed: bool) -> list[NDArray[np.float64]]:
    """The runs (k, 2) of consecutive finite pixels of a curve (n, 2); a closed curve's first and last runs
    joined."""
    finite = np.all(np.isfinite(pixels), axis=1)
    if closed and finite.all():
        return [np.vstack([pixels, pixels[:1]])]
    runs: list[NDArray[np.float64]] = []
    start = None
    for k, ok in enumerate([*finite.tolist(), False]):
        if ok and start is None:
            start = k
        elif not ok and start is not None:
            runs.append(pixels[start:k])
            start = None
    if closed and len(runs) > 1 and finite[0] and finite[-1]:
        runs[0] = np.vstack([runs.pop(), runs[0]])
    return [run for run in runs if len(run) > 1]


def _points(run: NDArray[np.float64]) -> NDArray[np.int32]:
    return np.round(run * SUBPIXEL).astype(np.int32).reshape(-1, 1, 2)


def _circle(
    canvas: NDArray[np.uint8], centre: tuple[float, float], radius: float, colour: tuple[int, int, int], width: int
) -> None:
    cv2.circle(canvas, at_subpixel(centre), round(radius * SUBPIXEL), colour, width, cv2.LINE_AA, SHIFT)


def _cross(canvas: NDArray[np.uint8], centre: tuple[float, float], colour: tuple[int, int, int], width: int) -> None:
    size = 12 * width
    u, v = centre
    cv2.line(canvas, at_subpixel((u - size, v)), at_subpixel((u + size, v)), colour, width, cv2.LINE_AA, SHIFT)
    cv2.line(canvas, at_subpixel((u, v - size)), at_subpixel((u, v + size)), colour, width, cv2.LINE_AA, SHIFT)


def _font_scale(thickness: int) -> float:
    return 0.45 * thickness


def _text(
    canvas: NDArray[np.uint8], text: str, where: tuple[float, float], colour: tuple[int, int, int], thickness: int
) -> None:
    """``text`` with its baseline's left end at ``where`` (px), outlined in black so that it reads on any image.

    The outline is the text drawn in black at the offsets around it, with the same thickness: OpenCV
    spaces the letters by their thickness, so a thicker black copy would drift from the text along a line.
    """
    u, v = round(where[0]), round(where[1])
    scale = _font_scale(thickness)
    for du in (-thickness, 0, thickness):
        for dv in (-thickness, 0, thickness):
            if du or dv:
                cv2.putText(
                    canvas, text, (u + du, v + dv), cv2.FONT_HERSHEY_SIMPLEX, scale, (0, 0, 0), thickness, cv2.LINE_AA
                )
    cv2.putText(canvas, text, (u, v), cv2.FONT_HERSHEY_SIMPLEX, scale, colour, thickness, cv2.LINE_AA)
