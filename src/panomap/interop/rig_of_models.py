"""A rig from its cameras' models and their poses relative to camera 0: each camera's table, in one world.

Convention (docs/conventions.md, "A rig"): camera k's pose is given in camera 0's frame (OpenCV's: x right, y
down, z ahead) as the axes ``A_k`` (3, 3; columns: camera k's x, y, z in camera 0's frame) and the centre ``t_k``
(3,); camera 0's is ``(I, 0)``. The rig's world is placed by camera 0's axes ``G_0`` (columns ``[R, Dn, F]`` of its
orientation's yaw, pitch and roll, :func:`panomap.camera.orientation.view_axes`) and centre ``c_0``, so camera k
looks along ``G_k = G_0 A_k`` from ``c_k = c_0 + G_0 t_k``; its table is
:func:`.table_of_camera.table_of_camera` of its model so placed. Every rig reader (a Kalibr camchain, Basalt's
``T_imu_cam``, a Hugin project) gives its cameras this way and builds its rig here.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..camera.orientation import angles_of_axes, view_axes
from ..errors import PanomapError
from ..geometry import FloatArray
from ..rig.rig import CameraRig
from .readers.base import Imported
from .table_of_camera import radius_of_fov, table_of_camera


@dataclass(frozen=True)
class RigCamera:
    """One camera of a rig as its file gives it: its name, its calibration, its pose in camera 0's frame."""

    name: str
    imported: Imported
    axes: FloatArray
    centre: FloatArray


def axes_of_orientation(orientation_rad: tuple[float, float, float]) -> FloatArray:
    """G (3, 3), columns ``[R, Dn, F]`` (world axes), of a yaw, pitch and roll (rad)."""
    forward, right, down = view_axes(*orientation_rad)
    return np.stack([right, down, forward], axis=1)


def rig_of_models(
    cameras: Sequence[RigCamera],
    path: str | Path,
    format: str,
    *,
    axes0: FloatArray,
    centre0: tuple[float, float, float] = (0.0, 0.0, 0.0),
    side_by_side: bool = False,
    size: tuple[int, int] | None = None,
    fov_rad: float | None = None,
    outer_radii: Sequence[float | None] | None = None,
) -> CameraRig:
    """The rig of ``cameras`` (two or more, camera 0 first), camera 0 looking along ``axes0`` from ``centre0``.

    Parameters
    ----------
    cameras : sequence of RigCamera
        Each camera's calibration and pose relative to camera 0 (the module's convention).
    path : path
        The file they came from (named in errors, and in each table's record and the rig's with its SHA-256).
    format : str
        Its format (``kalibr``, ``basalt``, ``hugin``), in the rig's record.
    axes0 : (3, 3)
        Camera 0's frame axes in the world (columns: right, down, ahead).
    centre0 : (X0, Y0, Z0)
        Camera 0's centre in the world (world units; the poses' translations are in the file's, metres).
    side_by_side : bool
        The cameras' pictures come side by side in one frame, camera 0 on the left.
    size : (M, N), optional
        Each table's size; default about one entry per pixel.
    fov_rad : float, optional
        Each lens's field of view across (rad): its table stops ``fov/2`` from its axis.
    outer_radii : sequence of float or None, optional
        Each camera's image circle (px about its principal point) where known; overrides ``fov_rad``.
    """
    if len(cameras) < 2:
        raise PanomapError(f"a rig needs two or more cameras; this file has {len(cameras)}", path)
    g0 = np.asarray(axes0, dtype=np.float64)
    c0 = np.asarray(centre0, dtype=np.float64)
    info = _rig_info(path, format, g0, centre0)
    tables, offsets, x = [], [], 0
    for k, camera in enumerate(cameras):
        imported = camera.imported
        if imported.image_size is None:
            raise PanomapError(f"{camera.name} gives no resolution", path)
        axes = g0 @ np.asarray(camera.axes, dtype=np.float64)
        centre = c0 + g0 @ np.asarray(camera.centre, dtype=np.float64)
        yaw, pitch, roll = angles_of_axes(axes[:, 2], axes[:, 0])
        record = {"file": Path(path).name, "sha256": info["source"]["sha256"], "format": imported.format,
                  "camera": camera.name, "pixel_shift_px": imported.pixel_shift_px}  # fmt: skip
        table_info = {
            "import": record,
            "sources": {"centre": f"imported from {Path(path).name}", "camera_position": f"the {imported.format} rig"},
            "warnings": [],
        }
        outer = None if outer_radii is None else outer_radii[k]
        if outer is None and fov_rad is not None:
            outer = radius_of_fov(imported.model, fov_rad)[0]
        try:
            table = table_of_camera(
                imported.model,
                outer_radius=outer,
                orientation_rad=(yaw, pitch, roll),
                camera_position=(float(centre[0]), float(centre[1]), float(centre[2])),
                image_size=imported.image_size,
                size=size,
                info=table_info,
            )
        except PanomapError as exc:
            raise PanomapError(f"{camera.name}: {exc.detail}", path) from None
        tables.append(table)
        offsets.append((x, 0))
        x += imported.image_size[0]
    names = tuple(camera.name for camera in cameras)
    return CameraRig(tuple(tables), names, tuple(offsets) if side_by_side else None, info)


def _rig_info(path: str | Path, format: str, axes0: FloatArray, centre0: Sequence[float]) -> dict[str, Any]:
    """The rig's record: its file (name, SHA-256, format), and camera 0's orientation (deg) and position."""
    digest = hashlib.sha256(Path(path).read_bytes()).hexdigest()
    yaw, pitch, roll = (math.degrees(a) for a in angles_of_axes(axes0[:, 2], axes0[:, 0]))
    return {
        "source": {"file": Path(path).name, "sha256": digest, "format": format},
        "camera0": {"yaw_deg": yaw, "pitch_deg": pitch, "roll_deg": roll, "position": [float(c) for c in centre0]},
    }
