"""The stretch along the axis: the cameras a picture's lines and right angles cannot tell apart.

Convention: rays and directions in the camera's axes, +z (or -z: the sign does not matter here) its optical axis,
unit vectors (n, 3); angles in degrees where the name says so.

Take a camera and stretch its rays along its own axis: the camera ``C_s`` that sees, at each pixel, the ray ``d``
of the first turned into ``S d / |S d|``, ``S = diag(1, 1, s)``: its azimuths are the first camera's, its angles
from the axis ``tan(alpha') = tan(alpha) / s``, and it is again a radial camera (``r = f(alpha(alpha'))``). ``S`` is
linear, so it maps each plane through the viewpoint onto a plane through the viewpoint: **a pixel lies exactly
as far from a line's image under ``C_s`` as under the first camera**, for every ``s``. Straightness cannot tell
``C_s`` from the camera. A direction ``D`` becomes ``S D``: two directions at right angles stay at right angles
when each lies along the axis or square to it (the vertical and the walls of a room, for a camera looking
straight down, straight up or along a wall), and the angle between two directions oblique to the axis moves
(``a`` off the axis and its perpendicular in the same plane: ``cos = sin a cos a (1 - s^2) / (|S d1| |S d2|)``).

A checkerboard is no better where it faces the axis (flat under a camera looking down or up, square before
one looking ahead: its plane ``z = h`` becomes ``z = s h``, its squares stay square: the stretch is the focal
length that fronto-parallel boards leave free for a pinhole camera). A board turned ``b`` from that sees its
squares' sides along the turn shortened by ``(1 - s^2) sin^2(b) / 2``.

So a picture whose lines run only along and across the axis pins the scale of the elevations by nothing but the
radial law's own stiffness, which no picture measures: no number of such pictures does. With the camera's
directions 1-3 deg off them (a level camera), a room must be square to hundredths of a degree for its right
angles to place the camera within a px (``bench/bench_line_floor.py``); rooms are square to tenths.
"""

from __future__ import annotations

import numpy as np

from ...geometry import FloatArray

#: A family of lines whose direction is within this of the axis or of square to it (deg) says little about the
#: stretch: a pair's angle turns by about ``sin(2 a) (1 - s^2) / 2`` rad, half its value at 45 deg here, a tenth at
#: 3 deg (a level camera's room).
OBLIQUE_MIN_DEG = 15.0

#: Boards that all face the axis within this (deg) cannot pin the stretch: a 10% stretch changes a square's sides
#: by ``(1 - s^2) sin^2(b) / 2``, under 0.3% here, about what a small board's corners measure. Measured: a real
#: paracatadioptric image's one board 7.5 deg off facing the axis, every corner within 0.34 px, its camera 78.7 px
#: (p90) from the calibration; rendered flat boards under a fisheye tilted 2 deg, 6.4 / 11.5 px (p90 / max).
FLAT_BOARD_DEG = 10.0


def axial_stretch(rays: FloatArray, s: float) -> FloatArray:
    """The rays (n, 3) of the camera stretched by ``s`` along its axis: ``S d / |S d|``, ``S = diag(1, 1, s)``."""
    out = np.asarray(rays, dtype=np.float64) * np.array([1.0, 1.0, s])
    return np.asarray(out / np.linalg.norm(out, axis=-1, keepdims=True), dtype=np.float64)


def obliqueness_deg(directions: FloatArray) -> FloatArray:
    """Each direction's (k, 3) angle (deg) from the nearer of the axis and the plane square to it: 0 along or
    across the axis, 45 halfway."""
    d = np.asarray(directions, dtype=np.float64)
    from_axis = np.degrees(np.arccos(np.clip(np.abs(d[:, 2]) / np.linalg.norm(d, axis=1), 0.0, 1.0)))
    return np.asarray(np.minimum(from_axis, 90.0 - from_axis), dtype=np.float64)
