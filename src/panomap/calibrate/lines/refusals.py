"""Why the straight lines found give no camera: each refusal's first line says what is missing and what to do
(no command-line option: the CLI adds those), the lines after it the figures (:attr:`PanomapError.figures`)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ...errors import PanomapError, refusal
from ...geometry import FloatArray

RIGHT_ANGLES = (
    "two families of parallel lines at right angles (a room's vertical and horizontal edges, a checkerboard's rows "
    "and columns) fix the scale of the elevations, which straightness alone leaves free: a picture of a built scene "
    "(a room, a corridor, a building) showing edges of its three directions gives them"
)
LONG_EDGES = (
    "long straight edges across the annulus (walls, door and window frames, shelves, floor tiles, a checkerboard), "
    "some vertical and some horizontal, in light"
)


def too_few(found: int, what: str, needed: int) -> PanomapError:
    """Fewer than ``needed`` arcs or lines (``what``) were found."""
    first = f"only {found} {what} found (at least {needed} are needed): give long straight edges, or a checkerboard"
    return PanomapError(refusal(first, LONG_EDGES))


def no_right_angles(lines: int) -> PanomapError:
    """``lines`` straight lines, but no two families of them at right angles."""
    first = f"{lines} straight lines but none at right angles to others"
    return PanomapError(refusal(f"{first}: give a picture of a room's corners, or a checkerboard", RIGHT_ANGLES))


def not_straight(kept: int, rms: FloatArray, long_enough: NDArray[np.bool_], limit: float, needed: int) -> PanomapError:
    """What was found where a start leaves fewer than ``needed`` straight arcs: how many arcs, how many were
    long enough to test, and how far from straight the rest were (a pattern of many short edges, such as a
    checkerboard tiled over the whole frame, gives edges that no camera makes straight lines)."""
    tested = rms[long_enough]
    spread = f", their RMS from straight {float(np.median(tested)):.2f} px (median)" if tested.size else ""
    return PanomapError(
        refusal(
            f"only {kept} of {rms.size} edge arcs are straight under any starting camera, {needed} needed: give "
            "long straight edges or a checkerboard",
            f"straight: within {limit:.2f} px; {int(long_enough.sum())} of the arcs long enough to test{spread}; "
            "long straight edges across the annulus: walls, door and window frames, shelves, a checkerboard",
        )
    )
