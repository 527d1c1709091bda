"""Landmark pairs from a simulated camera: world points spread in elevation, exact pixels.

The pairs are plain arrays (:class:`LandmarkPairs`): the simulation is the ground truth and
imports nothing from the code under test; ``Landmarks(*pairs)`` makes the library's type.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from panomap.simulate.cameras import SimulatedCamera


class LandmarkPairs(NamedTuple):
    """Simulated landmark point pairs, in the order of ``panomap.Landmarks``'s fields:
    ``pixels`` (n, 2) true (u, v) in px, ``world`` (n, 3) world points, ``names`` "L1", "L2", ...
    """

    pixels: NDArray[np.float64]
    world: NDArray[np.float64]
    names: tuple[str, ...]


def spread_landmarks(
    camera: SimulatedCamera,
    camera_position: tuple[float, float, float],
    count: int,
    rng: np.random.Generator,
    elevation_range: tuple[float, float] | None = None,
    distance_range: tuple[float, float] = (1.0, 4.0),
    pixel_noise: float = 0.0,
) -> LandmarkPairs:
    """``count`` landmarks evenly spread in elevation, at random azimuths and distances.

    Parameters
    ----------
    camera : SimulatedCamera
        Ground truth: its ``project`` gives each landmark's pixel.
    camera_position : (X0, Y0, Z0)
        O_m in world units; world points are O_m plus the simulated offsets.
    count : int
    rng : numpy.random.Generator
    elevation_range : (low, high), optional
        Elevations (rad) to spread over; default the camera's visible range,
        1 deg inside each end.
    distance_range : (near, far)
        Horizontal distances, world units.
    pixel_noise : float
        Standard deviation (px) of Gaussian noise added to each pixel.
    """
    low, high = elevation_range or camera.elevation_range
    margin = np.radians(1.0) if elevation_range is None else 0.0
    rho = np.linspace(low + margin, high - margin, count)
    theta = rng.uniform(0.0, 2 * np.pi, count)
    distance = rng.uniform(*distance_range, count)
    offsets = np.stack([distance * np.cos(theta), distance * np.sin(theta), distance * np.tan(rho)], axis=-1)
    pixels = camera.project(offsets)
    if not np.all(np.isfinite(pixels)):
        raise ValueError("a simulated landmark is not visible; narrow the elevation range")
    pixels = pixels + rng.normal(0.0, pixel_noise, pixels.shape) if pixel_noise > 0 else pixels
    names = tuple(f"L{k + 1}" for k in range(count))
    return LandmarkPairs(pixels, offsets + np.asarray(camera_position), names)
