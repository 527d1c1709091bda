"""The robust-fit scenarios: ceiling cameras in a 6 x 5 x 2.6 m room, noisy landmarks.

Used by ``bench/bench_fit.py`` and ``tests/test_fit_robust.py``. Landmarks lie
where rays from the camera hit the room's floor, walls (or ceiling); world
points get Gaussian noise in world units, pixels in px. The error of a fit is
the worst pixel error over test points at elevations -85..-5 deg that the
camera sees (``worst_error`` in ``tests/helpers.py``: this module is ground truth
and imports nothing from the code under test).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from panomap.geometry import ray_from_angles
from panomap.simulate.cameras import RadialCamera, SimulatedCamera, TiltedCamera, standard_cameras
from panomap.simulate.sampling import LandmarkPairs

ROOM_SIZE = (6.0, 5.0, 2.6)
CAMERA_POSITION = (3.1, 2.4, 2.45)
IMAGE_SIZE = (1920, 1920)
TEST_ELEVATIONS_DEG = (-85.0, -5.0)


def scenario_cameras() -> dict[str, RadialCamera]:
    """The issue's six ceiling cameras on 1920 x 1920 images (about 10 px per degree)."""
    outer = 0.47 * IMAGE_SIZE[0]
    middle = ((IMAGE_SIZE[0] - 1) / 2, (IMAGE_SIZE[1] - 1) / 2)
    deg = math.pi / 180

    def unified(name: str, xi: float, a_min: float, a_max: float, **kw: object) -> RadialCamera:
        scale = outer * (xi + math.cos(a_max * deg)) / math.sin(a_max * deg)
        return RadialCamera(
            name=name,
            law="unified",
            scale=scale,
            xi=xi,
            image_size=IMAGE_SIZE,
            centre=kw.pop("centre", middle),  # type: ignore[arg-type]
            alpha_min=a_min * deg,
            alpha_max=a_max * deg,
            **kw,  # type: ignore[arg-type]
        )

    return {
        "equidistant": RadialCamera(
            name="equidistant",
            law="equidistant",
            scale=outer / (95 * deg),
            image_size=IMAGE_SIZE,
            centre=middle,
            alpha_max=95 * deg,
        ),
        "equisolid": RadialCamera(
            name="equisolid",
            law="equisolid",
            scale=outer / (2 * math.sin(47.5 * deg)),
            image_size=IMAGE_SIZE,
            centre=middle,
            alpha_max=95 * deg,
        ),
        "parabolic": unified("parabolic", 1.0, 12, 105),
        "hyperbolic-0.9": unified("hyperbolic-0.9", 0.9, 12, 100),
        "hyperbolic-0.6": unified("hyperbolic-0.6", 0.6, 12, 100),
        "rotated-mirrored": unified(
            "rotated-mirrored", 0.8, 12, 100, centre=(middle[0] + 23.4, middle[1] - 17.8), s=-1, phi0=2.1
        ),
    }


def more_cameras() -> dict[str, SimulatedCamera]:
    """Cameras beyond the issue's six, on the same images, to check that the fit generalises: the other designed
    fisheye projections (stereographic 190 deg; orthographic 176 deg, whose law flattens at the rim), two lenses
    off their design by a polynomial (Kannala and Brandt's model: r = f (alpha + k1 alpha^3 + k2 alpha^5)),
    a weak hyperbolic mirror (xi 0.3) and a spherical mirror (no single viewpoint)."""
    outer = 0.47 * IMAGE_SIZE[0]
    middle = ((IMAGE_SIZE[0] - 1) / 2, (IMAGE_SIZE[1] - 1) / 2)

    def scaled(name: str, law: str, a_max_deg: float, a_min_deg: float = 0.0, **kw: object) -> RadialCamera:
        def make(scale: float) -> RadialCamera:
            return RadialCamera(
                name=name,
                law=law,
                scale=scale,
                image_size=IMAGE_SIZE,
                centre=middle,
                alpha_min=math.radians(a_min_deg),
                alpha_max=math.radians(a_max_deg),
                **kw,  # type: ignore[arg-type]
            )

        return make(outer / make(1.0).outer_radius)

    return {
        "stereographic": scaled("stereographic", "stereographic", 95),
        "orthographic": scaled("orthographic", "orthographic", 88),
        "lens-k1+": scaled("lens-k1+", "polynomial", 95, distortion=(0.04, -0.01)),
        "lens-k1-": scaled("lens-k1-", "polynomial", 100, distortion=(-0.05, 0.008)),
        "hyperbolic-0.3": scaled("hyperbolic-0.3", "unified", 100, 12, xi=0.3),
        "spherical": standard_cameras(size=IMAGE_SIZE)["spherical"],
    }


def hit_room(directions: NDArray[np.float64]) -> NDArray[np.float64]:
    """World points (..., 3) where rays from the camera meet the room's surfaces."""
    origin = np.asarray(CAMERA_POSITION)
    d = np.asarray(directions, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        t_low = (0.0 - origin) / d
        t_high = (np.asarray(ROOM_SIZE) - origin) / d
    t = np.where(d > 0, t_high, np.where(d < 0, t_low, np.inf))
    return origin + np.min(t, axis=-1, keepdims=True) * d


@dataclass(frozen=True)
class Trial:
    """One trial's landmarks, and which one (if any) was made an outlier."""

    landmarks: LandmarkPairs
    outlier: int | None = None


def make_landmarks(
    camera: SimulatedCamera,
    count: int,
    rng: np.random.Generator,
    *,
    spread: bool = True,
    pixel_sigma: float = 1.0,
    world_sigma: float = 0.01,
    outlier_px: float = 0.0,
) -> Trial:
    """Landmarks on the room's surfaces, evenly spread in elevation or at random, with noise.

    Elevations cover the camera's visible range less 2 deg at each end (in the
    camera's own axes, for a :class:`TiltedCamera`); with ``outlier_px`` one
    landmark's pixel is moved that far in a random direction.
    """
    low, high = camera.elevation_range
    low, high = low + math.radians(2), high - math.radians(2)
    rho = np.linspace(low, high, count) if spread else rng.uniform(low, high, count)
    theta = rng.uniform(0, 2 * math.pi, count)
    directions = ray_from_angles(theta, rho)
    if isinstance(camera, TiltedCamera):
        directions = directions @ camera.rotation.T
    world = hit_room(directions)
    pixels = camera.project(world - np.asarray(CAMERA_POSITION))
    pixels = pixels + rng.normal(0, pixel_sigma, pixels.shape)
    world = world + rng.normal(0, world_sigma, world.shape)
    outlier = None
    if outlier_px:
        outlier = int(rng.integers(count))
        angle = rng.uniform(0, 2 * math.pi)
        pixels[outlier] += outlier_px * np.array([math.cos(angle), math.sin(angle)])
    names = tuple(f"L{k + 1}" for k in range(count))
    return Trial(LandmarkPairs(pixels, world, names), outlier)


def test_points(camera: SimulatedCamera, count: int = 4000) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """World points at elevations -85..-5 deg on the room's surfaces that the camera sees, and their true pixels."""
    side = int(math.sqrt(count))
    theta, rho = np.meshgrid(
        np.linspace(0, 2 * math.pi, side, endpoint=False),
        np.radians(np.linspace(*TEST_ELEVATIONS_DEG, side)),
    )
    world = hit_room(ray_from_angles(theta.ravel(), rho.ravel()))
    truth = camera.project(world - np.asarray(CAMERA_POSITION))
    visible = np.all(np.isfinite(truth), axis=1)
    return world[visible], truth[visible]
