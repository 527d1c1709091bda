"""A rig from a Kalibr camchain of several cameras: each camera's table, placed by the chain's poses.

Convention (docs/conventions.md, "A rig"): a camchain's ``T_cn_cnm1`` takes a point from camera n-1's frame into
camera n's, ``x_n = R x_(n-1) + t`` (OpenCV frames: x right, y down, z ahead); the rig's world is placed by
camera 0's orientation (yaw, pitch, roll: its frame's axes ``G_0 = [R, Dn, F]``) and position ``c_0``. So
camera n's frame has the world axes ``G_n = G_(n-1) R^T`` and its centre is at ``c_n = c_(n-1) - G_(n-1) R^T t``:
the chain gives each camera's pose relative to camera 0 (:func:`camchain_cameras`), and
:func:`.rig_of_models.rig_of_models` makes each camera's table looking along ``G_n`` from ``c_n``.

The check (:func:`check_pose`): each ``T_cn_cnm1``'s rotation block must be a rotation (orthonormal to 1e-6,
determinant +1) and its bottom row (0, 0, 0, 1); a matrix that is not (a projection, a typo) is refused naming the
camera. An inverted or transposed pose is a rotation too: only the pictures tell it (:mod:`panomap.rig.check`).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .. import inputs
from ..errors import PanomapError
from ..files import read_text
from ..rig.check import PoseComparison, compare_poses
from ..rig.rig import CameraRig
from .readers.kalibr import looks_like, read_chain
from .rig_of_models import RigCamera, axes_of_orientation, rig_of_models

# How close to a rotation a camchain's rotation block must be.
ROTATION_TOLERANCE = 1e-6


def check_pose(
    matrix: NDArray[np.float64], name: str, path: str | Path
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(R (3, 3), t (3,)) of a 4 x 4 ``T_cn_cnm1``, refused unless R is a rotation and the last row (0, 0, 0, 1)."""
    rotation, translation = matrix[:3, :3], matrix[:3, 3]
    if not np.allclose(matrix[3], [0.0, 0.0, 0.0, 1.0], atol=1e-9):
        raise PanomapError(f"{name}.T_cn_cnm1's last row is {matrix[3].tolist()}, not 0 0 0 1", path)
    if not np.allclose(rotation @ rotation.T, np.eye(3), atol=ROTATION_TOLERANCE) or np.linalg.det(rotation) < 0:
        raise PanomapError(
            f"{name}.T_cn_cnm1's rotation block is not a rotation (orthonormal, determinant +1): a mistyped or "
            "scaled matrix",
            path,
        )
    return rotation, translation


def camchain_cameras(path: str | Path, flipped: int | None = None) -> list[RigCamera]:
    """Every camera of the camchain at ``path`` with its pose relative to camera 0 (:mod:`.rig_of_models`), the
    chain's ``x_n = R x_(n-1) + t`` composed: ``A_n = A_(n-1) R^T``, ``t_n = t_(n-1) - A_(n-1) R^T t``.
    ``flipped``: camera n's ``T_cn_cnm1`` taken inverted (``R^T``, ``-R^T t``), for the check of the pictures.
    """
    text = read_text(path)
    if not looks_like(text):
        raise PanomapError("not a Kalibr camchain (no camera_model entries): a rig is read from a camchain", path)
    axes, centre = np.eye(3), np.zeros(3)
    cameras = []
    for k, (imported, matrix) in enumerate(read_chain(text, path)):
        name = imported.camera or f"cam{k}"
        if matrix is not None:
            rotation, translation = check_pose(matrix, name, path)
            if flipped == k:
                rotation, translation = rotation.T, -rotation.T @ translation
            centre = centre - axes @ rotation.T @ translation
            axes = axes @ rotation.T
        cameras.append(RigCamera(name, imported, axes, centre))
    return cameras


def rig_of_camchain(
    path: str | Path,
    *,
    orientation_rad: tuple[float, float, float] = (0.0, 0.0, 0.0),
    camera_position: tuple[float, float, float] = (0.0, 0.0, 0.0),
    side_by_side: bool = False,
    size: tuple[int, int] | None = None,
    fov_rad: float | None = None,
    outer_radii: tuple[float | None, ...] | None = None,
    flipped: int | None = None,
) -> CameraRig:
    """The rig of every camera of the Kalibr camchain at ``path``.

    Parameters
    ----------
    path : path
        A camchain of two or more cameras, each after the first with its ``T_cn_cnm1``.
    orientation_rad : (yaw, pitch, roll)
        Camera 0's orientation in the world (rad; default looking ahead along +X, level).
    camera_position : (X0, Y0, Z0)
        Camera 0's centre in the world (world units; the chain's translations are in the camchain's, metres).
    side_by_side : bool
        The cameras' pictures come side by side in one frame, camera 0 on the left (a dual-fisheye camera's
        raw frame).
    size : (M, N), optional
        Each table's size; default about one entry per pixel.
    fov_rad : float, optional
        Each lens's field of view across (rad): its table stops ``fov/2`` from its axis (a 360 camera's lenses
        see 190-200 deg; beyond, the frame holds their black rims, which must not join the blend).
    outer_radii : tuple of float or None, optional
        Each camera's image circle (px about its principal point), where found in its picture; overrides
        ``fov_rad`` for that camera.
    flipped : int, optional
        Take camera ``flipped``'s ``T_cn_cnm1`` inverted (the check's alternative).
    """
    orientation_rad = _three(inputs.numbers(orientation_rad, 3, "orientation_rad (yaw, pitch, roll)"))
    camera_position = _three(inputs.numbers(camera_position, 3, "the camera position (X0, Y0, Z0)"))
    if fov_rad is not None and not 0.0 < inputs.number(fov_rad, "fov_rad") <= 2.0 * math.pi:
        raise PanomapError(f"fov_rad must be more than 0 and at most 2 pi (360 deg, in radians), not {fov_rad:g}")
    cameras = camchain_cameras(path, flipped)
    if outer_radii is not None and (isinstance(outer_radii, str) or len(outer_radii) != len(cameras)):
        raise PanomapError(f"give one outer radius (or None) per camera ({len(cameras)}), not {outer_radii!r:.40}")
    if flipped is not None and flipped not in range(1, len(cameras)):
        raise PanomapError(f"flipped must name a camera after the first (1 to {len(cameras) - 1}), not {flipped!r}")
    if len(cameras) < 2:
        raise PanomapError("a rig needs two or more cameras; this camchain has one (import makes its table)", path)
    axes0 = axes_of_orientation(orientation_rad)
    return rig_of_models(cameras, path, "kalibr", axes0=axes0, centre0=camera_position, side_by_side=side_by_side,
                         size=size, fov_rad=fov_rad, outer_radii=outer_radii)  # fmt: skip


# The tables of the rigs the pictures check compares (its view is 1.4 deg a pixel).
CHECK_TABLE_SIZE = (1024, 256)


def check_camchain_pictures(
    path: str | Path,
    pictures: Any,
    *,
    orientation_rad: tuple[float, float, float] = (0.0, 0.0, 0.0),
    side_by_side: bool = False,
    fov_rad: float | None = None,
    outer_radii: tuple[float | None, ...] | None = None,
) -> PoseComparison:
    """The camchain's rig measured in ``pictures`` (:func:`panomap.rig.check.compare_poses`) as given and with each
    camera's ``T_cn_cnm1`` inverted in turn (labelled by the camera's name): an inverted pose and one whose rotation
    block is transposed turn the camera alike (``R^T``), and the pictures (at infinity) cannot tell them apart."""
    options: dict[str, Any] = {"orientation_rad": orientation_rad, "side_by_side": side_by_side,
                               "fov_rad": fov_rad, "outer_radii": outer_radii, "size": CHECK_TABLE_SIZE}  # fmt: skip
    given = rig_of_camchain(path, **options)
    alternatives = {given.names[n]: rig_of_camchain(path, flipped=n, **options) for n in range(1, given.count)}
    return compare_poses(given, alternatives, pictures)


def _three(values: tuple[float, ...]) -> tuple[float, float, float]:
    return values[0], values[1], values[2]
