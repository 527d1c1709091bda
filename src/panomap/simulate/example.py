"""A simulated camera to learn, with known answers: for the learning page's tests and screenshots.

(``tests/test_learn*.py`` and ``docs/make_screenshots.py``; it lives here, not in
:mod:`panomap.learn`, because it is ground truth and the shipped tool does not use it.)

The bundled room rendered through a simulated ceiling camera (hyperbolic
mirror, rotated and mirrored, centre off the image middle), and the room's
landmarks with their true pixels, computed by the simulated camera's
closed-form projection (outside the code under test).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from panomap.simulate.cameras import SimulatedCamera, standard_cameras
from panomap.simulate.room import load_room, render


@dataclass(frozen=True)
class Example:
    """A rendered omni-image and true landmarks.

    Attributes
    ----------
    image : (H, W, 3) uint8 ndarray
    camera : SimulatedCamera
        The ground truth.
    camera_position : (X0, Y0, Z0)
        O_m in the room, metres.
    names : tuple of str
    world : (n, 3) ndarray
        Landmark world points, metres, spread in elevation.
    pixels : (n, 2) ndarray
        Their true pixels (u, v).
    """

    image: NDArray[np.uint8]
    camera: SimulatedCamera
    camera_position: tuple[float, float, float]
    names: tuple[str, ...]
    world: NDArray[np.float64]
    pixels: NDArray[np.float64]


def make_example(size: tuple[int, int] = (640, 640), count: int = 8, supersample: int = 2) -> Example:
    """Render the room at ``size`` and choose ``count`` visible landmarks spread evenly in elevation."""
    room = load_room()
    position = np.asarray(room.camera, dtype=float)
    width, height = size
    centre = (width / 2 - 2.3, height / 2 + 1.7)
    camera: Any = standard_cameras(size, centre=centre, s=-1, phi0=0.6)["hyperbolic"]
    image = render(room, camera, supersample=supersample)
    names, points = room.landmarks()
    pixels = camera.project(points - position)
    visible = np.flatnonzero(np.all(np.isfinite(pixels), axis=1))
    d = points[visible] - position
    elevation = np.arctan2(d[:, 2], np.hypot(d[:, 0], d[:, 1]))
    order = visible[np.argsort(elevation)]
    chosen = order[np.unique(np.round(np.linspace(0, len(order) - 1, count)).astype(int))]
    return Example(
        image=image,
        camera=camera,
        camera_position=(float(position[0]), float(position[1]), float(position[2])),
        names=tuple(names[k] for k in chosen),
        world=points[chosen],
        pixels=pixels[chosen],
    )
