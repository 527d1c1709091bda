"""A rig from a Basalt calibration JSON of several cameras, placed by each camera's ``T_imu_cam``.

Convention: ``T_imu_cam`` (translation ``p``, unit quaternion ``q`` as x, y, z, w) takes a point from the camera's
frame (OpenCV's) into the IMU's: ``x_imu = R(q) x_cam + p``. Relative to camera 0, camera k's axes are
``A_k = R_0^T R_k`` and its centre ``t_k = R_0^T (p_k - p_0)`` (:mod:`.rig_of_models`); camera 0 is placed by the
orientation and position given, as for a camchain.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import PanomapError
from ..files import read_text
from ..geometry import FloatArray
from ..rig.rig import CameraRig
from .readers import basalt
from .readers.base import RigPose
from .rig_of_models import RigCamera, axes_of_orientation, rig_of_models

# How far from 1 a pose's quaternion's norm may be.
QUATERNION_TOLERANCE = 1e-3


def rotation_of_quaternion(pose: RigPose, path: str | Path) -> FloatArray:
    """R (3, 3) of a pose's unit quaternion (x, y, z, w); refused unless its norm is 1 within 1e-3."""
    x, y, z, w = pose.quaternion_xyzw
    norm = float(np.sqrt(x * x + y * y + z * z + w * w))
    if abs(norm - 1.0) > QUATERNION_TOLERANCE:
        raise PanomapError(f"{pose.camera}'s T_imu_cam quaternion has norm {norm:.6g}, not 1", path)
    x, y, z, w = (q / norm for q in (x, y, z, w))
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def basalt_cameras(path: str | Path) -> list[RigCamera]:
    """Every camera of the Basalt file with its pose relative to camera 0."""
    text = read_text(path)
    first = basalt.read(text, path, None)
    if not first.rig_poses:
        raise PanomapError("value0.T_imu_cam is missing: a rig needs each camera's pose", path)
    poses = first.rig_poses
    r0 = rotation_of_quaternion(poses[0], path)
    p0 = np.asarray(poses[0].translation_m, dtype=np.float64)
    cameras = []
    for k, pose in enumerate(poses):
        imported = first if k == 0 else basalt.read(text, path, str(k))
        rotation = rotation_of_quaternion(pose, path)
        centre = r0.T @ (np.asarray(pose.translation_m, dtype=np.float64) - p0)
        cameras.append(RigCamera(pose.camera, imported, r0.T @ rotation, centre))
    return cameras


def rig_of_basalt(
    path: str | Path,
    *,
    orientation_rad: tuple[float, float, float] = (0.0, 0.0, 0.0),
    camera_position: tuple[float, float, float] = (0.0, 0.0, 0.0),
    side_by_side: bool = False,
    size: tuple[int, int] | None = None,
    fov_rad: float | None = None,
    outer_radii: tuple[float | None, ...] | None = None,
) -> CameraRig:
    """The rig of every camera of the Basalt calibration at ``path`` (parameters as :func:`.rig_of_camchain`)."""
    cameras = basalt_cameras(path)
    axes0 = axes_of_orientation(orientation_rad)
    return rig_of_models(cameras, path, "basalt", axes0=axes0, centre0=camera_position, side_by_side=side_by_side,
                         size=size, fov_rad=fov_rad, outer_radii=outer_radii)  # fmt: skip
