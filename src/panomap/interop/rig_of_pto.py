"""A rig from a Hugin (PanoTools) project of several images: each image a camera, in Hugin's world.

Convention: each image's yaw, pitch and roll (PanoTools', deg) give its camera's axes ``G_k`` in panomap's world
(:func:`.readers.hugin_pto.axes_of_ypr`: Hugin's panorama centre along +X, Z up; a camera of ``y, p, r`` looks
yaw ``-y``, pitch ``p``, roll ``r``). Every camera sits at the position given (a 360 camera's lenses share a
centre as far as a project knows): relative to camera 0, camera k's axes are ``G_0^T G_k`` and its centre 0
(:mod:`.rig_of_models`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import PanomapError
from ..files import read_text
from ..rig.rig import CameraRig
from .readers.hugin_pto import axes_of_ypr, looks_like, read_images
from .rig_of_models import RigCamera, rig_of_models


def pto_cameras(path: str | Path) -> tuple[list[RigCamera], np.ndarray]:
    """Every image of the project as a camera with its pose relative to camera 0, and camera 0's axes (world)."""
    text = read_text(path)
    if not looks_like(text):
        raise PanomapError("not a PanoTools project (no i line with w and h, no p line)", path)
    images = read_images(text, path)
    axes = [axes_of_ypr(*ypr) for _, ypr in images]
    cameras = [
        RigCamera(imported.camera or f"cam{k}", imported, axes[0].T @ g, np.zeros(3))
        for k, ((imported, _), g) in enumerate(zip(images, axes, strict=True))
    ]
    return cameras, axes[0]


def rig_of_pto(
    path: str | Path,
    *,
    camera_position: tuple[float, float, float] = (0.0, 0.0, 0.0),
    side_by_side: bool = False,
    size: tuple[int, int] | None = None,
    fov_rad: float | None = None,
    outer_radii: tuple[float | None, ...] | None = None,
) -> CameraRig:
    """The rig of every image of the Hugin project at ``path``, in Hugin's world (parameters as
    :func:`.rig_of_camchain.rig_of_camchain`; the orientations are the project's)."""
    cameras, axes0 = pto_cameras(path)
    return rig_of_models(cameras, path, "hugin", axes0=axes0, centre0=camera_position, side_by_side=side_by_side,
                         size=size, fov_rad=fov_rad, outer_radii=outer_radii)  # fmt: skip
