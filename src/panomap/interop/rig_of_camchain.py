"""A rig from a Kalibr camchain of several cameras: each camera's table, placed by the chain's poses.

Convention (docs/conventions.md, "A rig"): a camchain's ``T_cn_cnm1`` takes a point from camera n-1's frame into
camera n's, ``x_n = R x_(n-1) + t`` (OpenCV frames: x right, y down, z ahead); the rig's world is placed by
camera 0's orientation (yaw, pitch, roll: its frame's axes ``G_0 = [R, Dn, F]``) and position ``c_0``. So
camera n's frame has the world axes ``G_n = G_(n-1) R^T`` and its centre is at ``c_n = c_(n-1) - G_(n-1) R^T t``.
Each camera's table is then :func:`.table_of_camera.table_of_camera` of its model looking along ``G_n`` from
``c_n``.

The check (:func:`check_pose`): each ``T_cn_cnm1``'s rotation block must be a rotation (orthonormal to 1e-6,
determinant +1) and its bottom row (0, 0, 0, 1); a matrix that is not (a projection, a typo) is refused naming the
camera. An inverted or transposed pose is a rotation too: only the pictures tell it (:mod:`panomap.rig.check`).
"""

from __future__ import annotations

import hashlib
import math
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..camera.orientation import angles_of_axes, view_axes
from ..errors import PanomapError
from ..files import read_text
from ..rig.rig import CameraRig
from .readers.kalibr import looks_like, read_chain
from .table_of_camera import radius_profile, table_of_camera

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


def rig_of_camchain(
    path: str | Path,
    *,
    orientation_rad: tuple[float, float, float] = (0.0, 0.0, 0.0),
    camera_position: tuple[float, float, float] = (0.0, 0.0, 0.0),
    side_by_side: bool = False,
    size: tuple[int, int] | None = None,
    fov_rad: float | None = None,
    outer_radii: tuple[float | None, ...] | None = None,
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
    """
    text = read_text(path)
    if not looks_like(text):
        raise PanomapError("not a Kalibr camchain (no camera_model entries): a rig is read from a camchain", path)
    chain = read_chain(text, path)
    frame = view_axes(*orientation_rad)
    axes = np.stack([frame[1], frame[2], frame[0]], axis=1)  # [R, Dn, F]
    centre = np.asarray(camera_position, dtype=np.float64)
    digest = hashlib.sha256(Path(path).read_bytes()).hexdigest()
    tables: list[Any] = []
    names: list[str] = []
    offsets: list[tuple[int, int]] = []
    x = 0
    for imported, matrix in chain:
        name = imported.camera or f"cam{len(names)}"
        if matrix is not None:
            rotation, translation = check_pose(matrix, name, path)
            centre = centre - axes @ rotation.T @ translation
            axes = axes @ rotation.T
        if imported.image_size is None:
            raise PanomapError(f"{name} gives no resolution", path)
        yaw, pitch, roll = angles_of_axes(axes[:, 2], axes[:, 0])
        info = {
            "import": {"file": Path(path).name, "sha256": digest, "format": "kalibr", "camera": name,
                       "pixel_shift_px": 0.0},
            "sources": {"centre": f"imported from {Path(path).name}", "camera_position": "the camchain's chain"},
            "warnings": [],
        }  # fmt: skip
        outer = None if outer_radii is None else outer_radii[len(names)]
        if outer is None and fov_rad is not None:
            profile = radius_profile(imported.model, min(math.pi, fov_rad / 2 + 0.05))
            outer = float(profile.radius_at(np.array([fov_rad / 2]))[0])
        try:
            table = table_of_camera(
                imported.model,
                outer_radius=outer,
                orientation_rad=(yaw, pitch, roll),
                camera_position=(float(centre[0]), float(centre[1]), float(centre[2])),
                image_size=imported.image_size,
                size=size,
                info=info,
            )
        except PanomapError as exc:
            raise PanomapError(f"{name}: {exc.detail}", path) from None
        tables.append(table)
        names.append(name)
        offsets.append((x, 0))
        x += imported.image_size[0]
    if len(tables) < 2:
        raise PanomapError("a rig needs two or more cameras; this camchain has one (import makes its table)", path)
    rig_info = {
        "source": {"file": Path(path).name, "sha256": digest, "format": "kalibr"},
        "camera0": {
            "yaw_deg": math.degrees(orientation_rad[0]),
            "pitch_deg": math.degrees(orientation_rad[1]),
            "roll_deg": math.degrees(orientation_rad[2]),
            "position": list(camera_position),
        },
    }
    return CameraRig(tuple(tables), tuple(names), tuple(offsets) if side_by_side else None, rig_info)
