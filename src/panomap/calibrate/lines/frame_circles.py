"""The image circles the line fit starts from, also where the image shows no rim.

Convention: pixel (u, v), u the column, v the row, the centre of the top-left pixel at (0, 0); radii in px.

A mirror image that overfills the frame, or a full-frame fisheye, has no rim to find: the line fit needs
no rim (the lines fix the centre), only a centre to start from and the region its edges are taken in.
The start is the cut-off disc's centre where one shows (the camera's own reflection: a mirror camera),
else the middle of the frame; the region is the whole frame (the "image circle" reaches its farthest
corner) outside the cut-off disc.
"""

from __future__ import annotations

import math
from typing import Any

from numpy.typing import NDArray

from ..circles import Circle, ImageCircles, NoImageCircle, find_image_circles


def line_circles(image: NDArray[Any]) -> ImageCircles:
    """The image circles of ``image`` ((H, W[, C])), or, where no rim is visible, the stand-in above.

    Raises
    ------
    PanomapError
        What :func:`find_image_circles` raises, but for :class:`NoImageCircle`.
    """
    try:
        return find_image_circles(image)
    except NoImageCircle as exc:
        return frame_circles((image.shape[1], image.shape[0]), exc.frame_centre, exc.cutoff)


def frame_circles(size: tuple[int, int], frame_centre: tuple[float, float], cutoff: Circle | None) -> ImageCircles:
    """Stand-in circles for an image of ``size`` (W, H) px with no rim: centred on the cut-off disc ``cutoff``
    where there is one, else on ``frame_centre``; the outer circle through the frame's farthest corner."""
    width, height = size
    centre = cutoff.centre if cutoff is not None else frame_centre
    reach = max(
        math.hypot(corner_u - centre[0], corner_v - centre[1])
        for corner_u in (-0.5, width - 0.5)
        for corner_v in (-0.5, height - 0.5)
    )
    outer = Circle(centre=centre, radius=reach, rms_px=math.inf, inliers=0, rays=0)
    return ImageCircles(
        centre=centre,
        outer=outer,
        cutoff=cutoff,
        ellipse=None,
        cropped_by=("left", "top", "right", "bottom"),
        rim_in_frame=0.0,
        rim_seen=0.0,
        rim_polarity="mixed",
    )
