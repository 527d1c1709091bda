"""A soft rim found at a coarser scale: the picture shrunk until its rim is sharp again, the rim found there and
its circle taken back to full resolution.

Convention: pixel (u, v), u the column, v the row, the centre of the top-left pixel at (0, 0); radii in px. A
picture shrunk by an integer factor ``f`` (by area) has its sample k at full-resolution ``(k + 0.5) * f - 0.5``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from .sampling import _full_resolution
from .thresholds import COARSER_FACTORS, COARSER_LEAST_SIDE_PX, COARSER_MAX_RMS_PX
from .types import Circle, _Rim


def shrunk(grey: NDArray[Any], factor: int) -> NDArray[np.float32]:
    """``grey`` (H, W) shrunk by area by an integer ``factor``: (H // factor, W // factor)."""
    height, width = grey.shape
    return np.asarray(cv2.resize(grey, (width // factor, height // factor), interpolation=cv2.INTER_AREA), np.float32)


def at_full_resolution(rim: _Rim, factor: int) -> _Rim:
    """A rim found in the picture shrunk by ``factor``, in full-resolution px (centre, radius, RMS, points)."""
    circle = rim.circle
    points = (np.asarray(rim.points, dtype=np.float64) + 0.5) * factor - 0.5
    return _Rim(
        circle=Circle(
            centre=_full_resolution(circle.centre, factor),
            radius=circle.radius * factor,
            rms_px=circle.rms_px * factor,
            inliers=circle.inliers,
            rays=circle.rays,
        ),
        points=points,
        rays_in_frame=rim.rays_in_frame,
        polarity=rim.polarity,
        stepping=rim.stepping,
    )


def coarser_rim(grey: NDArray[Any], search: Callable[[NDArray[np.float32], float], _Rim | None]) -> _Rim | None:
    """The rim ``search`` finds in ``grey`` (H, W) shrunk by each of COARSER_FACTORS (1: as it is), its edge points
    on a circle within the RMS it is given (px of the picture it is given), in full-resolution px; None where it
    finds none.

    A soft rim (a field stop out of focus, vignetting that falls to the pedestal over tens of px) spreads its
    drop over so many px that the full-resolution search's steps (levels 2-12 px either side of the rim, edge
    points on a circle to 2 px RMS) do not see it: a rendered fisheye in a dark square, its stop blurred by 6
    px, was said to be full-frame. Shrunk by 2 or 4, the same rim is 1-3 px wide and the same tests, in the
    shrunk picture's px, pass. A rim is kept only where its edge points lie on a circle within
    COARSER_MAX_RMS_PX (of the shrunk picture's px: a clear rim, not a circle through a full-frame fisheye's
    scene); of those, the one whose fit is best in full-resolution px (the scale at which the rim is sharpest).
    """
    found: list[_Rim] = []
    for factor in COARSER_FACTORS:
        small = shrunk(grey, factor) if factor > 1 else np.asarray(grey, np.float32)
        if min(small.shape) < COARSER_LEAST_SIDE_PX:
            break
        rim = search(small, COARSER_MAX_RMS_PX)
        if rim is not None:
            found.append(at_full_resolution(rim, factor))
    return min(found, key=lambda rim: rim.circle.rms_px, default=None)
