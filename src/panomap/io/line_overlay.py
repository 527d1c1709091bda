"""What a fit from lines saw, drawn on the omni-image: every line used with its residual, the arcs set
aside and why, and the elevation bands with no line.

Convention: pixels (u, v), u the column, v the row; colours BGR.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from ..calibrate.circles import ImageCircles
from ..calibrate.core.report import table_fit_report
from ..calibrate.lines.arcs import EdgeArc
from ..errors import PanomapError
from ..table.table import PanoMappingTable
from .overlay import SHIFT, SUBPIXEL, at_subpixel, draw_legend, overlay_canvas

USED = (60, 220, 60)
WORSE = (0, 200, 255)  # a line used whose RMS is over twice the noise
REJECTED = (40, 40, 230)
EMPTY_BAND = (255, 120, 0)
TEXT = (255, 255, 255)
FOUND = (0, 230, 255)  # an edge arc found, where no camera was learned


def draw_line_overlay(
    image: NDArray[Any], table: PanoMappingTable, arcs: Sequence[EdgeArc], image_index: int = 0
) -> NDArray[np.uint8]:
    """An 8-bit BGR copy of ``image`` (input ``image_index`` of the fit) with the fit's lines drawn on it.

    Lines used: green (orange where their RMS residual is over twice the edge noise), labelled with it in
    px; arcs set aside: red, with their reason's first words; elevation bands without a line: blue circles
    at their ends; the centre: a cross.

    Raises
    ------
    PanomapError
        If the table holds no line fit report.
    """
    report = table_fit_report(table)
    if report is None or report.lines is None:
        raise PanomapError("the table was not learned from lines: it has no lines to draw")
    lines = report.lines
    canvas, thickness = overlay_canvas(image)
    scale = 0.4 * thickness
    for line in lines.lines:
        if line.image_index != image_index:
            continue
        colour = WORSE if line.rms_px > 2 * lines.sigma_px else USED
        for k in line.arcs:
            _polyline(canvas, arcs[k].pixels, colour, 2 * thickness)
        middle = arcs[line.arcs[0]].pixels[len(arcs[line.arcs[0]].pixels) // 2]
        _label(canvas, f"{line.rms_px:.2f}", middle, colour, scale, thickness)
    for arc in lines.rejected:
        if arc.image_index != image_index:
            continue
        pixels = arcs[arc.arc].pixels
        _polyline(canvas, pixels, REJECTED, thickness)
        word = "curved" if arc.reason.startswith("not straight") else "short"
        _label(canvas, f"{word} {arc.rms_px:.1f}", pixels[len(pixels) // 2], REJECTED, scale, thickness)
    for low, high in lines.empty_bands_deg:
        for elevation in (low, high):
            theta = np.linspace(0.0, 2 * np.pi, 720)
            pixels = np.asarray(table.sample(theta, np.full_like(theta, np.radians(elevation))), dtype=np.float64)
            _polyline(canvas, pixels, EMPTY_BAND, thickness)
    u, v = table.model.centre
    size = 10 * thickness
    cv2.line(canvas, at_subpixel((u - size, v)), at_subpixel((u + size, v)), TEXT, thickness, cv2.LINE_AA, SHIFT)
    cv2.line(canvas, at_subpixel((u, v - size)), at_subpixel((u, v + size)), TEXT, thickness, cv2.LINE_AA, SHIFT)
    legend = [
        f"{len(lines.lines)} lines used (green; orange: over 2x the noise): RMS {lines.rms_px:.2f}, max "
        f"{lines.max_px:.2f} px",
        f"{len(lines.rejected)} arcs set aside (red); blue: bands without a line",
    ]
    draw_legend(canvas, legend, thickness, TEXT)
    return canvas


def draw_found_overlay(
    image: NDArray[Any], arcs: Sequence[EdgeArc], circles: ImageCircles | None, why: str, image_index: int = 0
) -> NDArray[np.uint8]:
    """An 8-bit BGR copy of ``image`` with the edge arcs found in it (yellow) and its image circles, where no
    camera was learned: what the fit had to work with, and ``why`` it gave no camera (its first words)."""
    canvas, thickness = overlay_canvas(image)
    mine = [arc for arc in arcs if arc.image_index == image_index]
    for arc in mine:
        _polyline(canvas, arc.pixels, FOUND, 2 * thickness)
    if circles is not None:
        for radius in (circles.cutoff_radius, circles.outer_radius):
            if radius:
                cv2.circle(canvas, at_subpixel(circles.centre), round(radius * SUBPIXEL), EMPTY_BAND, thickness,
                           cv2.LINE_AA, SHIFT)  # fmt: skip
    legend = [f"no camera: {why}", f"{len(mine)} edge arcs found (yellow); blue: the image circles"]
    draw_legend(canvas, legend, thickness, TEXT)
    return canvas


def _polyline(canvas: NDArray[np.uint8], pixels: NDArray[np.float64], colour: tuple[int, int, int], width: int) -> None:
    finite = np.all(np.isfinite(pixels), axis=1)
    runs = np.split(np.flatnonzero(finite), np.flatnonzero(np.diff(np.flatnonzero(finite)) > 1) + 1)
    for run in runs:
        if run.size > 1:
            points = np.round(pixels[run] * SUBPIXEL).astype(np.int32).reshape(-1, 1, 2)
            cv2.polylines(canvas, [points], False, colour, width, cv2.LINE_AA, SHIFT)


def _label(
    canvas: NDArray[np.uint8],
    text: str,
    where: NDArray[np.float64],
    colour: tuple[int, int, int],
    scale: float,
    thickness: int,
) -> None:
    at = (round(float(where[0])), round(float(where[1])))
    cv2.putText(canvas, text, at, cv2.FONT_HERSHEY_SIMPLEX, scale, (0, 0, 0), thickness + 2, cv2.LINE_AA)
    cv2.putText(canvas, text, at, cv2.FONT_HERSHEY_SIMPLEX, scale, colour, thickness, cv2.LINE_AA)
