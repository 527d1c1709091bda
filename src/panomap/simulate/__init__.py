"""Simulated omni-cameras and a textured room, as ground truth for tests and demos.

Cameras (:mod:`panomap.simulate.cameras`) project points given relative to the nominal
camera position O_m and trace pixels back to rays; the room (:mod:`panomap.simulate.room`)
renders omni-images through any of them. Conventions: ``docs/conventions.md``.
"""

from panomap.simulate.cameras import (
    RADIAL_LAWS,
    SVP_CAMERA_NAMES,
    RadialCamera,
    SimulatedCamera,
    SphericalMirrorCamera,
    TiltedCamera,
    mount_rotation,
    standard_cameras,
)
from panomap.simulate.degrade import (
    dark_square,
    field_stop,
    halo,
    housed_mirror,
    lit_ring,
    noisy_jpeg,
    over_exposed,
    side_glow,
    vignette,
)
from panomap.simulate.room import (
    WALL_NAMES,
    Opening,
    Room,
    Wall,
    load_room,
    render,
    render_rays,
)
from panomap.simulate.sampling import LandmarkPairs, spread_landmarks

__all__ = [
    "RADIAL_LAWS",
    "SVP_CAMERA_NAMES",
    "WALL_NAMES",
    "LandmarkPairs",
    "Opening",
    "RadialCamera",
    "Room",
    "SimulatedCamera",
    "SphericalMirrorCamera",
    "TiltedCamera",
    "Wall",
    "dark_square",
    "field_stop",
    "halo",
    "housed_mirror",
    "lit_ring",
    "load_room",
    "mount_rotation",
    "noisy_jpeg",
    "over_exposed",
    "render",
    "render_rays",
    "side_glow",
    "spread_landmarks",
    "standard_cameras",
    "vignette",
]
