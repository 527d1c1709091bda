"""Angles of a camera learned from lines: its elevations from alpha, its annulus, its default handedness.

Convention: alpha is a ray's angle (rad) from the pole the image centre sees (this package's axes); the
camera's elevation rho is ``alpha - pi/2`` looking down, ``pi/2 - alpha`` looking up.
"""

from __future__ import annotations

import numpy as np

from ...camera.radial import RadialFunction
from ...camera.radial_models import rho_of_alpha
from ..circles import ImageCircles
from .rays import InverseRadial


def annulus_deg(radial: RadialFunction, circles: ImageCircles, r_max: float) -> tuple[float, float]:
    """Camera elevations (deg, low to high) from the cut-off disc (or the axis) to the farthest line radius."""
    inverse = InverseRadial.of(radial, r_max)
    radii = np.array([circles.cutoff_radius or 0.0, min(circles.outer_radius, r_max)])
    alpha, _ = inverse(radii)
    rho = np.degrees(rho_of_alpha(alpha, radial.axis))
    return float(rho.min()), float(rho.max())


def default_handedness(mirror: bool, axis: str) -> int:
    """The handedness s an image has when nothing says otherwise, from the kind of camera.

    A lens looking down sees east at +u and north at -v (a map seen from above): s = -1; looking up,
    s = +1. A mirror camera (its camera looking at the mirror, the mirror's azimuth theta showing the
    world's theta) flips that: +1 when its image centre sees down (the paper's case), -1 up.
    """
    return 1 if mirror != (axis == "up") else -1
