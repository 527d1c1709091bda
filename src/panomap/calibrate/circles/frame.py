"""What the frame cuts of a circle: edges crossed, quadrants and sectors in the frame, the rim's
visible arcs.
"""

from __future__ import annotations

import math

import numpy as np

from ...geometry import FloatArray
from .thresholds import FRAME_EDGES, INLIER_SIGMAS, MIN_RIM_FRACTION, MIN_RIM_RAYS, MIN_RIM_SHARE_IN_FRAME, RAYS
from .types import Circle


def _least_rim_rays(centre: tuple[float, float], radius: float, shape: tuple[int, int], polarity: int) -> float:
    """Rays (of RAYS) whose edge points a rim about ``centre`` of ``radius`` (px) needs: MIN_RIM_FRACTION of
    them, or, where the frame shows less of the circle, MIN_RIM_SHARE_IN_FRAME of those it shows (at least
    MIN_RIM_RAYS). Not for a rim of either polarity (``polarity`` 0), which no step across it confirms: a
    mirror in a housing, whose rim the frame does not cut that much."""
    if not polarity:
        return MIN_RIM_FRACTION * RAYS
    shown = _fraction_in_frame(centre, radius, shape) * RAYS
    return max(MIN_RIM_RAYS, min(MIN_RIM_FRACTION * RAYS, MIN_RIM_SHARE_IN_FRAME * shown))


def _sectors_seen(points: FloatArray, circle: Circle) -> int:
    """Sectors of 30 deg (of 12) in which at least a third of the rays have a point on the circle."""
    du, dv = points[:, 0] - circle.centre[0], points[:, 1] - circle.centre[1]
    on = np.abs(np.hypot(du, dv) - circle.radius) < max(INLIER_SIGMAS * circle.rms_px, 0.5)
    sector = (np.floor(np.arctan2(dv[on], du[on]) / (math.pi / 6)).astype(np.int64)) % 12
    return int(np.sum(np.bincount(sector, minlength=12) >= RAYS / 12 / 3))


def _arcs(points: FloatArray, circle: Circle) -> tuple[tuple[float, float], ...]:
    """The arcs (start, end deg) the points on the circle cover: gaps up to 2 deg bridged, arcs under 2 deg dropped."""
    du, dv = points[:, 0] - circle.centre[0], points[:, 1] - circle.centre[1]
    on = np.abs(np.hypot(du, dv) - circle.radius) < max(INLIER_SIGMAS * circle.rms_px, 0.5)
    seen = np.zeros(360, dtype=bool)
    seen[np.floor(np.degrees(np.arctan2(dv[on], du[on])) % 360).astype(np.int64) % 360] = True
    if seen.all():
        return ((0.0, 360.0),)
    # Bridge gaps of up to 2 deg, then read the runs from the first degree not seen.
    bridged = seen | (np.roll(seen, 1) & np.roll(seen, -2)) | (np.roll(seen, 2) & np.roll(seen, -1))
    start = int(np.argmin(bridged))
    runs, begin = [], None
    for k in range(start, start + 361):
        if bridged[k % 360] and begin is None:
            begin = k
        elif not bridged[k % 360] and begin is not None:
            if k - begin >= 2:
                runs.append((float(begin % 360), float(begin % 360 + k - begin)))
            begin = None
    return tuple(sorted(runs))


def _quadrants(points: FloatArray, shape: tuple[int, int]) -> int:
    """How many quarters of the frame (about its middle) hold at least 10 of the points (n, 2)."""
    height, width = shape
    quarter = 2 * (points[:, 0] > (width - 1) / 2) + (points[:, 1] > (height - 1) / 2)
    return int(np.sum(np.bincount(quarter.astype(np.int64), minlength=4) >= 10))


def _cropping_edges(centre: tuple[float, float], radius: float, shape: tuple[int, int]) -> tuple[str, ...]:
    """The frame edges that cut the circle, in the order left, top, right, bottom."""
    height, width = shape
    u, v = centre
    beyond = (u - radius < -0.5, v - radius < -0.5, u + radius > width - 0.5, v + radius > height - 0.5)
    return tuple(edge for edge, cut in zip(FRAME_EDGES, beyond, strict=True) if cut)


def _sectors_in_frame(circle: Circle, shape: tuple[int, int]) -> int:
    """Sectors of 30 deg (of 12) of the circle in which at least a third of the rays fall in the frame."""
    height, width = shape
    angles = (np.arange(RAYS) + 0.5) * (2 * math.pi / RAYS)
    u = circle.centre[0] + circle.radius * np.cos(angles)
    v = circle.centre[1] + circle.radius * np.sin(angles)
    inside = (u >= -0.5) & (u <= width - 0.5) & (v >= -0.5) & (v <= height - 0.5)
    return int(np.sum(inside.reshape(12, -1).mean(axis=1) >= 1 / 3))


def _fraction_in_frame(centre: tuple[float, float], radius: float, shape: tuple[int, int]) -> float:
    """Fraction of the circle's circumference inside the frame."""
    height, width = shape
    angles = np.linspace(0.0, 2 * math.pi, 3600, endpoint=False)
    u = centre[0] + radius * np.cos(angles)
    v = centre[1] + radius * np.sin(angles)
    return float(np.mean((u >= -0.5) & (u <= width - 0.5) & (v >= -0.5) & (v <= height - 0.5)))


# px: the last rows and columns of a frame are often darker or softer than the rest.
FRAME_MARGIN_PX = 1.5


def away_from_frame(points: FloatArray, shape: tuple[int, ...]) -> FloatArray:
    """The rows of ``points`` (n, 2) [u, v] px more than FRAME_MARGIN_PX inside a frame of ``shape`` (H, W)."""
    height, width = shape[:2]
    margin = FRAME_MARGIN_PX
    away = (
        (points[:, 0] > margin)
        & (points[:, 0] < width - 1 - margin)
        & (points[:, 1] > margin)
        & (points[:, 1] < height - 1 - margin)
    )
    return points[away]
