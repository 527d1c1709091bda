"""The learning page's "learn from lines": the camera learned from the image's straight lines, no landmark needed.

Convention: pixel (u, v) = (column, row), the centre of the top-left pixel at (0, 0); residuals in px.

The same fit and table as ``panomap fit -o T --image IMG [--azimuth-zero U V]``
(:func:`panomap.calibrate.pictures.learn_from_images`, which both call), on
the arcs of the page's image found once (:class:`panomap.calibrate.landmarks.joint.ImageLines`, shared with the landmark
fit, which the same lines join). Lines know no azimuth origin: a click on the image sets the pixel that sees
world azimuth 0 (:func:`panomap.calibrate.lines.orientation.zero_azimuth`, what ``--azimuth-zero U V`` does).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..calibrate.core.report import table_fit_report
from ..calibrate.landmarks.joint import ImageLines
from ..calibrate.lines.arcs import EdgeArc
from ..calibrate.lines.fit import LineFit
from ..calibrate.pictures import learn_from_images
from ..geometry import FloatArray
from ..table.table import PanoMappingTable

# Points per arc sent to the page to draw it (evenly along it).
POINTS_PER_ARC_SHOWN = 48


@dataclass(frozen=True)
class LineLearning:
    """A camera learned from the page's lines: the fit, its table, and the pixel that fixes azimuth 0 (or None);
    ``arcs``: what the fit's report indexes (the edge arcs, or the checkerboards' rows and columns)."""

    fit: LineFit
    table: PanoMappingTable
    azimuth_zero: tuple[float, float] | None
    arcs: Sequence[EdgeArc]


def learn_from_lines(
    image: NDArray[Any], lines: ImageLines, image_name: str, azimuth_zero: tuple[float, float] | None = None
) -> LineLearning:
    """The camera of ``image`` as the command learns it (:func:`panomap.calibrate.pictures.learn_from_images`:
    the image's checkerboards first, else its edge arcs, with the command's defaults) from its ``lines`` found
    beforehand, and its table; azimuth 0 at ``azimuth_zero`` (u, v) px when given, else at image angle 0.

    Raises
    ------
    PanomapError
        As the line fit does (too few lines, no two orthogonal families), or where the camera does not see
        ``azimuth_zero``.
    """
    learned = learn_from_images(
        [image],
        names=[image_name],
        azimuth_zero=azimuth_zero,
        info={"learned_with": f"panomap learn on {image_name}"},
        found=lines,
    )
    return LineLearning(learned.fit, learned.table, azimuth_zero, learned.arcs)


def _shown(pixels: FloatArray) -> list[list[float]]:
    """At most POINTS_PER_ARC_SHOWN points evenly along an arc, rounded to 0.01 px."""
    pixels = np.asarray(pixels, dtype=np.float64)
    if len(pixels) > POINTS_PER_ARC_SHOWN:
        pixels = pixels[np.round(np.linspace(0, len(pixels) - 1, POINTS_PER_ARC_SHOWN)).astype(int)]
    return [[round(float(u), 2), round(float(v), 2)] for u, v in pixels.tolist()]


def line_status(learning: LineLearning, lines: ImageLines, revision: int, horizon: Any) -> dict[str, Any]:
    """What the page shows of a camera learned from lines, JSON-ready: the report's sentences and figures, every
    line used (its arcs' points and its RMS, px) and every arc set aside (with why), the centre, the tilt, the
    azimuth origin and ``horizon`` (the table's horizon, as the landmark fit's status sends it)."""
    report = learning.fit.report
    model = learning.table.model
    tilt_deg, toward_deg = (math.degrees(a) for a in model.tilt)
    fit = table_fit_report(learning.table)
    uncertainty = None if fit is None or fit.uncertainty is None else fit.uncertainty.max_se_px
    used = [
        {
            "points": [_shown(learning.arcs[k].pixels) for k in line.arcs],
            "rms_px": line.rms_px,
            "family": line.family,
        }
        for line in report.lines
    ]
    rejected = [{"points": _shown(learning.arcs[arc.arc].pixels), "reason": arc.reason} for arc in report.rejected]
    origin = "the pixel clicked" if learning.azimuth_zero is not None else "image angle 0 (+u): click to set it"
    sentences = [
        *report.sentences(),
        f"tilt {tilt_deg:.2f} deg toward azimuth {toward_deg:.1f} deg" if report.vertical_lines else "",
        f"azimuth 0 is {origin}; handedness s = {model.s:+d} ({report.handedness_source})",
        "" if uncertainty is None else f"standard error of the radius: at most {uncertainty:.2f} px",
        "distances unknown (lines know none): floor, cylinder and plane views need panomap fit --camera-height H",
    ]
    m, n = learning.table.size
    return {
        "ok": True,
        "revision": revision,
        "message": (
            f"learned from {report.boards} checkerboard(s), {report.corners} corners: model {report.model}, corner "
            f"RMS {report.corner_rms_px:.2f} px, max {report.max_px:.2f} px"
            if report.boards
            else f"learned from {len(report.lines)} lines: model {report.model}, RMS {report.rms_px:.2f} px, "
            f"max {report.max_px:.2f} px"
        ),
        "boards": report.boards,
        "sentences": [s for s in sentences if s],
        "model": report.model,
        "lines_used": len(report.lines),
        "arcs_rejected": len(report.rejected),
        "rms_px": report.rms_px,
        "max_px": report.max_px,
        "sigma_px": report.sigma_px,
        "centre": list(model.centre),
        "tilt_deg": tilt_deg,
        "tilt_toward_deg": toward_deg,
        "vertical_lines": report.vertical_lines,
        "s": model.s,
        "azimuth_zero": None if learning.azimuth_zero is None else list(learning.azimuth_zero),
        "table_size": [m, n],
        "used": used,
        "rejected": rejected,
        "horizon": horizon,
    }
