"""Kalibr's camchain YAML (``camchain.yaml``, ``camchain-imucam.yaml``): one entry per camera (``cam0``, ...).

Each camera's fields read here: ``camera_model``, ``intrinsics``, ``distortion_model``,
``distortion_coeffs``, ``resolution`` ([width, height]). The models:

| camera_model | intrinsics | distortion_model: distortion_coeffs | panomap model |
| --- | --- | --- | --- |
| ``pinhole`` | fu, fv, pu, pv | ``equidistant``: k1 k2 k3 k4 | kannala-brandt |
| ``pinhole`` | fu, fv, pu, pv | ``radtan``: k1 k2 r1 r2 (or ``none``: []) | pinhole-radtan |
| ``omni`` | xi, fu, fv, pu, pv | ``radtan``: k1 k2 r1 r2, or ``none`` | mei |
| ``ds`` | xi, alpha, fu, fv, pu, pv | ``none`` | double-sphere |
| ``eucm`` | alpha, beta, fu, fv, pu, pv | ``none`` | eucm |

Kalibr's pixels are OpenCV's (the centre of the top-left pixel at (0, 0)), so nothing is shifted.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import yaml

from ...errors import PanomapError
from ..models.base import ExternalCamera
from ..models.double_sphere import DoubleSphere
from ..models.eucm import EUCM
from ..models.kannala_brandt import KannalaBrandt
from ..models.mei import Mei
from ..models.pinhole_radtan import PinholeRadtan
from .base import Imported, built, image_size_of, numbers

INTRINSIC_COUNTS = {"pinhole": 4, "omni": 5, "ds": 6, "eucm": 6}
DISTORTION_COUNTS = {"equidistant": 4, "radtan": 4, "none": 0}


# libyaml's loader where PyYAML has it: the same safe loader, about 100 times faster (a camchain followed by
# 100 MB of comments: 0.3 s, not 34 s).
_LOADER: Any = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
# A camera's entry as a camchain writes it: an indented ``camera_model:`` key (or one in a flow mapping).
_CAMERA_MODEL_KEY = re.compile(r"(^[ \t]+|[{,][ \t]*)[\"']?camera_model[\"']?[ \t]*:", re.MULTILINE)


def parse(text: str, path: str | Path) -> Any:
    """The YAML document ``text`` (parsed once: detection does not parse it)."""
    try:
        return yaml.load(text, Loader=_LOADER)  # (a safe loader)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" (line {mark.line + 1})" if mark is not None else ""
        raise PanomapError(f"not valid YAML{where}", path) from None


def looks_like(text: str) -> bool:
    """Whether ``text`` reads as a camchain: a camera's indented ``camera_model:`` key, found in the text
    without parsing it (the reader parses it once, and names what is wrong)."""
    return "camera_model" in text and "opencv-matrix" not in text and _CAMERA_MODEL_KEY.search(text) is not None


def read(text: str, path: str | Path, choice: str | None = None) -> Imported:
    data = parse(text, path)
    if not isinstance(data, dict):
        raise PanomapError("not a Kalibr camchain (no cam0, cam1, ... entries)", path)
    cameras = {str(k): v for k, v in data.items() if isinstance(v, dict) and "camera_model" in v}
    if not cameras:
        raise PanomapError("no camera in it has a camera_model (not a Kalibr camchain)", path)
    name = choice if choice is not None else ("cam0" if "cam0" in cameras else next(iter(cameras)))
    if name not in cameras:
        raise PanomapError(f"no camera {name!r} (it has {', '.join(cameras)})", path)
    camera = cameras[name]
    for key in ("intrinsics", "distortion_model", "resolution"):
        if key not in camera:
            raise PanomapError(f"{name}.{key} is missing", path)
    kind = str(camera["camera_model"])
    if kind not in INTRINSIC_COUNTS:
        raise PanomapError(f"{name}.camera_model {kind!r} is not one of {', '.join(INTRINSIC_COUNTS)}", path)
    distortion = str(camera["distortion_model"])
    if distortion not in DISTORTION_COUNTS:
        raise PanomapError(f"{name}.distortion_model {distortion!r} is not one of {', '.join(DISTORTION_COUNTS)}", path)
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
    allowed = {"pinhole": ("equidistant", "radtan", "none"), "omni": ("radtan", "none")}.get(kind, ("none",))
    if distortion not in allowed:
        raise PanomapError(
            f"{name}.distortion_model {distortion!r} does not go with camera_model {kind!r} "
            f"(it takes {', '.join(allowed)})",
            path,
        )
    if kind == "pinhole":
        cls = KannalaBrandt if distortion == "equidistant" else PinholeRadtan
        return built(cls, path, *intrinsics, *(coefficients or [0.0] * 4))
    if kind == "omni":
        xi, fu, fv, pu, pv = intrinsics
        return built(Mei, path, xi, fu, fv, pu, pv, *(coefficients or [0.0] * 4))
    if kind == "ds":
        return built(DoubleSphere, path, *intrinsics)
    return built(EUCM, path, *intrinsics)
