"""Edge arcs of an omni-image: the candidate images of straight world lines.

Convention: pixel (u, v), u the column, v the row, the centre of the top-left pixel at (0, 0)
(docs/conventions.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..circles import ImageCircles


@dataclass(frozen=True)
class EdgeArc:
    """One smooth edge curve of an omni-image: a candidate image of one straight world line.

    Attributes
    ----------
    pixels : (N, 2) float64, px
        Sub-pixel edge points ``[u, v]`` ordered along the curve, N >= 8.
    image_index : int
        Which input image, 0-based.
    contrast : float
        Median gradient magnitude across the edge (grey levels / px).
    """

    pixels: NDArray[np.float64]
    image_index: int
    contrast: float


def find_arcs(image: NDArray[np.generic], circles: ImageCircles, *, image_index: int = 0) -> list[EdgeArc]:
    """Edge arcs inside the usable annulus of ``image`` ((H, W) or (H, W, 3) uint8).

    Between the cut-off disc and the image circle, away from the frame's edge; split at corners;
    short, weak and noisy chains dropped.
    """
    raise NotImplementedError("find_arcs is being written")
