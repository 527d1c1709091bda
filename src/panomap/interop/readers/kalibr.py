"""Kalibr's camchain YAML (``camchain.yaml``, ``camchain-imucam.yaml``): one entry per camera (``cam0``, ...).

Each camera's fields read here: ``camera_model``, ``intrinsics``, ``distortion_model``,
``distortion_coeffs``, ``resolution`` ([width, height]). The models:

| camera_model | intrinsics | distortion_model: distortion_coeffs | panomap model |
| --- | --- | --- | --- |
| ``pinhole`` | fu, fv, pu, pv | ``equidistant``: k1 k2 k3 k4 | kannala-brandt |
| ``pinhole`` | fu, fv, pu, pv | ``radtan``: k1 k2 r1 r2 (or ``none``: []) | pinhole-radtan |
| ``pinhole`` | fu, fv, pu, pv | ``fov``: w | fov (the FOV model, as COLMAP's) |
| ``omni`` | xi, fu, fv, pu, pv | ``radtan``: k1 k2 r1 r2, or ``none`` | mei |
| ``ds`` | xi, alpha, fu, fv, pu, pv | ``none`` | double-sphere |
| ``eucm`` | alpha, beta, fu, fv, pu, pv | ``none`` | eucm |

Kalibr's pixels are OpenCV's (the centre of the top-left pixel at (0, 0)), so nothing is shifted. The
file is read within the bounds of :mod:`.yaml_text` (size, nesting, alias expansion); a first line
``%YAML:1.0`` (OpenCV's, which some projects put on their camchains) is skipped. An ``eucm`` alpha of 1
or more is refused, as Kalibr refuses it.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ...errors import PanomapError
from ..models.base import ExternalCamera
from ..models.colmap_fisheye import FOV
from ..models.double_sphere import DoubleSphere
from ..models.eucm import EUCM
from ..models.kannala_brandt import KannalaBrandt
from ..models.mei import Mei
from ..models.pinhole_radtan import PinholeRadtan
from .base import Imported, built, image_size_of, numbers
from .yaml_text import brief, load_yaml

INTRINSIC_COUNTS = {"pinhole": 4, "omni": 5, "ds": 6, "eucm": 6}
DISTORTION_COUNTS = {"equidistant": 4, "radtan": 4, "fov": 1, "none": 0}
# A camera's entry as a camchain writes it: a ``camera_model:`` key (or one in a flow mapping). A file naming
# it at the top level is claimed too, so that the reader says why it is not a camchain.
CAMERA_MODEL_KEY = re.compile(r"(^|[{,])[ \t]*[\"']?camera_model[\"']?[ \t]*:", re.MULTILINE)


def looks_like(text: str) -> bool:
    """Whether ``text`` reads as a camchain: a ``camera_model:`` key, found in the text
    without parsing it (the reader parses it once, within bounds, and names what is wrong)."""
    return "camera_model" in text and "opencv-matrix" not in text and CAMERA_MODEL_KEY.search(text) is not None


def read(text: str, path: str | Path, choice: str | None = None) -> Imported:
    data = load_yaml(text, path)
    if not isinstance(data, dict):
        raise PanomapError("not a Kalibr camchain (no cam0, cam1, ... entries)", path)
    cameras = {str(k): v for k, v in data.items() if isinstance(v, dict) and "camera_model" in v}
    if not cameras:
        raise PanomapError("no camera in it has a camera_model (not a Kalibr camchain)", path)
    name = choice if choice is not None else ("cam0" if "cam0" in cameras else next(iter(cameras)))
    if name not in cameras:
        raise PanomapError(f"no camera {name!r} (it has {brief(list(cameras))})", path)
    camera = cameras[name]
    for key in ("intrinsics", "distortion_model", "resolution"):
        if key not in camera:
            raise PanomapError(f"{name}.{key} is missing", path)
    kind = camera["camera_model"]
    if not isinstance(kind, str) or kind not in INTRINSIC_COUNTS:
        raise PanomapError(f"{name}.camera_model {brief(kind)} is not one of {', '.join(INTRINSIC_COUNTS)}", path)
    distortion = camera["distortion_model"]
    if not isinstance(distortion, str) or distortion not in DISTORTION_COUNTS:
        raise PanomapError(
            f"{name}.distortion_model {brief(distortion)} is not one of {', '.join(DISTORTION_COUNTS)}", path
        )
    intrinsics = numbers(camera["intrinsics"], f"{name}.intrinsics", path, INTRINSIC_COUNTS[kind])
    coefficients = numbers(
        camera.get("distortion_coeffs", []), f"{name}.distortion_coeffs", path, DISTORTION_COUNTS[distortion]
    )
    width, height = numbers(camera["resolution"], f"{name}.resolution", path, 2)
    size = image_size_of(width, height, f"{name}.resolution", path)
    return Imported(_model(kind, distortion, intrinsics, coefficients, name, path), "kalibr", size, name)


def _model(
    kind: str, distortion: str, intrinsics: list[float], coefficients: list[float], name: str, path: str | Path
) -> ExternalCamera:
    allowed = {"pinhole": ("equidistant", "radtan", "fov", "none"), "omni": ("radtan", "none")}.get(kind, ("none",))
    if distortion not in allowed:
        raise PanomapError(
            f"{name}.distortion_model {distortion!r} does not go with camera_model {kind!r} "
            f"(it takes {', '.join(allowed)})",
            path,
        )
    if kind == "pinhole" and distortion == "fov":
        return built(FOV, path, *intrinsics, *coefficients)
    if kind == "pinhole":
        cls = KannalaBrandt if distortion == "equidistant" else PinholeRadtan
        return built(cls, path, *intrinsics, *(coefficients or [0.0] * 4))
    if kind == "omni":
        xi, fu, fv, pu, pv = intrinsics
        return built(Mei, path, xi, fu, fv, pu, pv, *(coefficients or [0.0] * 4))
    if kind == "ds":
        return built(DoubleSphere, path, *intrinsics)
    if intrinsics[0] >= 1:
        raise PanomapError(f"{name}.intrinsics: eucm's alpha is {intrinsics[0]:g}; Kalibr takes it below 1", path)
    return built(EUCM, path, *intrinsics)


def read_chain(text: str, path: str | Path) -> list[tuple[Imported, NDArray[np.float64] | None]]:
    """Every camera of a camchain, in its order (cam0, cam1, ...), with its ``T_cn_cnm1`` (4, 4): the transform
    taking a point in the previous camera's frame into its own, ``x_n = R x_(n-1) + t`` (None for the first).

    Raises
    ------
    PanomapError
        Naming the camera: a camera after the first without ``T_cn_cnm1``, or one that is not 4 x 4 numbers.
    """
    data = load_yaml(text, path)
    if not isinstance(data, dict):
        raise PanomapError("not a Kalibr camchain (no cam0, cam1, ... entries)", path)
    names = [str(k) for k, v in data.items() if isinstance(v, dict) and "camera_model" in v]
    if not names:
        raise PanomapError("no camera in it has a camera_model (not a Kalibr camchain)", path)
    out: list[tuple[Imported, NDArray[np.float64] | None]] = []
    for k, name in enumerate(names):
        imported = read(text, path, name)
        entry = data[name]
        if k == 0:
            out.append((imported, None))
            continue
        if "T_cn_cnm1" not in entry:
            raise PanomapError(
                f"{name}.T_cn_cnm1 is missing: the rig needs each camera's pose from the one before", path
            )
        rows = entry["T_cn_cnm1"]
        if not isinstance(rows, list) or len(rows) != 4:
            raise PanomapError(f"{name}.T_cn_cnm1 is {brief(rows)}, not 4 rows of 4 numbers", path)
        matrix = np.array([numbers(row, f"{name}.T_cn_cnm1[{i}]", path, 4) for i, row in enumerate(rows)])
        out.append((imported, matrix))
    return out
