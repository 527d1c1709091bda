"""Basalt's calibration JSON (cereal's archive of ``basalt::Calibration``): ``{"value0": {...}}``.

Read: ``intrinsics`` (a list, one entry a camera: ``camera_type`` and its ``intrinsics`` by name),
``resolution`` ([[width, height], ...], the same order) and ``T_imu_cam`` (each camera's pose, kept in
:attr:`.base.Imported.rig_poses`, not yet used); the IMU's fields are not read. The cameras are named
``cam0``, ``cam1``, ... in the file's order (as Kalibr names them); ``--camera-name`` takes a name or an
index (default the first).

| camera_type | intrinsics | panomap model |
| --- | --- | --- |
| ``ds`` | fx fy cx cy xi alpha | double-sphere |
| ``eucm`` | fx fy cx cy alpha beta | eucm |
| ``ucm`` | fx fy cx cy alpha | eucm with beta = 1 (the same equations) |
| ``kb4`` | fx fy cx cy k1 k2 k3 k4 | kannala-brandt (theta = atan2(r, z): past 90 deg) |
| ``pinhole-radtan8`` | fx fy cx cy k1 k2 p1 p2 k3 k4 k5 k6 | pinhole-radtan |
| ``pinhole`` | fx fy cx cy | pinhole-radtan (no distortion) |

Basalt's frame and pixels are OpenCV's: nothing is shifted. Its ``fov`` and ``bal`` cameras are refused
naming them. The file is read within the bounds of :mod:`.json_text`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ...errors import PanomapError
from ..models.base import ExternalCamera
from ..models.double_sphere import DoubleSphere
from ..models.eucm import EUCM
from ..models.kannala_brandt import KannalaBrandt
from ..models.pinhole_radtan import PinholeRadtan
from .base import Imported, RigPose, built, image_size_of, member, numbers, typed_number
from .json_text import load_json
from .yaml_text import brief

# Each camera_type: its intrinsics' names in Basalt's order, and the model built from them (in that order).
CAMERA_TYPES: dict[str, tuple[tuple[str, ...], Any]] = {
    "ds": (
        ("fx", "fy", "cx", "cy", "xi", "alpha"),
        lambda fx, fy, cx, cy, xi, a: (DoubleSphere, xi, a, fx, fy, cx, cy),
    ),
    "eucm": (("fx", "fy", "cx", "cy", "alpha", "beta"), lambda fx, fy, cx, cy, a, b: (EUCM, a, b, fx, fy, cx, cy)),
    "ucm": (("fx", "fy", "cx", "cy", "alpha"), lambda fx, fy, cx, cy, a: (EUCM, a, 1.0, fx, fy, cx, cy)),
    "kb4": (("fx", "fy", "cx", "cy", "k1", "k2", "k3", "k4"), lambda *p: (KannalaBrandt, *p)),
    "pinhole-radtan8": (
        ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6"),
        lambda *p: (PinholeRadtan, *p),
    ),
    "pinhole": (("fx", "fy", "cx", "cy"), lambda *p: (PinholeRadtan, *p)),
}
POSE_KEYS = ("px", "py", "pz", "qx", "qy", "qz", "qw")


def looks_like(text: str) -> bool:
    """Whether ``text`` reads as Basalt's: a JSON object with ``value0``, ``intrinsics`` and ``camera_type``
    (found without parsing)."""
    return text.lstrip("\ufeff \t\r\n").startswith("{") and all(
        f'"{key}"' in text for key in ("value0", "intrinsics", "camera_type")
    )


def read(text: str, path: str | Path, choice: str | None = None) -> Imported:
    data = load_json(text, path)
    if not isinstance(data, dict) or not isinstance(data.get("value0"), dict):
        raise PanomapError('not a Basalt calibration (no "value0" object)', path)
    root = data["value0"]
    cameras = member(root, "intrinsics", path, list, "a list", "value0")
    if not cameras:
        raise PanomapError("value0.intrinsics is empty: no camera", path)
    resolutions = member(root, "resolution", path, list, "a list", "value0")
    if len(resolutions) != len(cameras):
        raise PanomapError(
            f"value0.resolution has {len(resolutions)} entries for {len(cameras)} cameras in value0.intrinsics", path
        )
    index = _index(choice, len(cameras), path)
    name = f"cam{index}"
    where = f"value0.intrinsics[{index}]"
    camera = cameras[index]
    if not isinstance(camera, dict):
        raise PanomapError(f"{where} is {brief(camera)}, not an object", path)
    for key in ("camera_type", "intrinsics"):
        if key not in camera:
            raise PanomapError(f"{where}.{key} is missing", path)
    kind = camera["camera_type"]
    if not isinstance(kind, str) or kind not in CAMERA_TYPES:
        raise PanomapError(f"{where}.camera_type {brief(kind)} is not read (it reads {', '.join(CAMERA_TYPES)})", path)
    intrinsics = camera["intrinsics"]
    if not isinstance(intrinsics, dict):
        raise PanomapError(f"{where}.intrinsics is {brief(intrinsics)}, not an object", path)
    keys, build = CAMERA_TYPES[kind]
    for key in keys:
        if key not in intrinsics:
            raise PanomapError(f"{where}.intrinsics.{key} is missing ({kind} takes {', '.join(keys)})", path)
    values = [typed_number(intrinsics[key], f"{where}.intrinsics.{key}", path) for key in keys]
    cls, *parameters = build(*values)
    model: ExternalCamera = built(cls, path, *parameters)
    width, height = numbers(resolutions[index], f"value0.resolution[{index}]", path, 2)
    size = image_size_of(width, height, f"value0.resolution[{index}]", path)
    return Imported(model, "basalt", size, name, rig_poses=_poses(root, len(cameras), path))


def _index(choice: str | None, count: int, path: str | Path) -> int:
    """The camera ``choice`` names (``cam1`` or ``1``; None: the first)."""
    if choice is None:
        return 0
    text = choice[3:] if choice.startswith("cam") else choice
    if text.isdigit() and int(text) < count:
        return int(text)
    names = ", ".join(f"cam{i}" for i in range(count))
    raise PanomapError(f"no camera {choice!r} (it has {names}, or their indices 0..{count - 1})", path)


def _poses(root: dict[str, Any], count: int, path: str | Path) -> tuple[RigPose, ...]:
    """Every camera's ``T_imu_cam`` (none where the file has none)."""
    if "T_imu_cam" not in root:
        return ()
    poses = member(root, "T_imu_cam", path, list, "a list", "value0")
    if len(poses) != count:
        raise PanomapError(f"value0.T_imu_cam has {len(poses)} entries for {count} cameras", path)
    out = []
    for i, pose in enumerate(poses):
        where = f"value0.T_imu_cam[{i}]"
        if not isinstance(pose, dict) or any(key not in pose for key in POSE_KEYS):
            raise PanomapError(f"{where} is {brief(pose)}, not a pose ({', '.join(POSE_KEYS)})", path)
        px, py, pz, qx, qy, qz, qw = (typed_number(pose[key], f"{where}.{key}", path) for key in POSE_KEYS)
        out.append(RigPose(f"cam{i}", (px, py, pz), (qx, qy, qz, qw)))
    return tuple(out)
