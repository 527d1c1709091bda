"""COLMAP's ``cameras.txt``: ``CAMERA_ID MODEL WIDTH HEIGHT PARAMS[]`` a line, ``#`` comments.

Models are identified by **name** (the numeric ids of ``cameras.bin`` differ across COLMAP versions).
Read, with their parameters in COLMAP's order:

| MODEL | PARAMS | panomap model |
| --- | --- | --- |
| ``OPENCV_FISHEYE`` | fx fy cx cy k1 k2 k3 k4 | opencv-fisheye |
| ``FOV`` | fx fy cx cy omega | colmap-fov |
| ``SIMPLE_RADIAL_FISHEYE`` | f cx cy k | colmap-radial-fisheye |
| ``RADIAL_FISHEYE`` | f cx cy k1 k2 | colmap-radial-fisheye |
| ``THIN_PRISM_FISHEYE`` | fx fy cx cy k1 k2 p1 p2 k3 k4 sx1 sy1 | colmap-thin-prism-fisheye |
| ``EUCM`` | fx fy cx cy alpha beta | colmap-eucm (Kalibr orders it alpha beta fx fy cx cy; COLMAP sees z > 0 only) |
| ``PINHOLE``, ``OPENCV`` | fx fy cx cy [k1 k2 p1 p2] | pinhole-radtan |

COLMAP puts the centre of the top-left pixel at (0.5, 0.5): cx and cy are read **minus 0.5**.
"""

from __future__ import annotations

import re
from pathlib import Path

from ...errors import PanomapError
from ..models.base import ExternalCamera
from ..models.colmap_fisheye import ColmapFOV, ColmapRadialFisheye, ColmapThinPrismFisheye
from ..models.eucm import ColmapEUCM
from ..models.kannala_brandt import OpenCVFisheye
from ..models.pinhole_radtan import PinholeRadtan
from .base import Imported, built, image_size_of
from .base import number as check_number

# COLMAP's pixel centres sit at +0.5 against panomap's (and OpenCV's, Kalibr's).
COLMAP_PIXEL_SHIFT = -0.5
PARAMETER_COUNTS = {
    "OPENCV_FISHEYE": 8,
    "FOV": 5,
    "SIMPLE_RADIAL_FISHEYE": 4,
    "RADIAL_FISHEYE": 5,
    "THIN_PRISM_FISHEYE": 12,
    "EUCM": 6,
    "PINHOLE": 4,
    "OPENCV": 8,
}
_LINE = re.compile(r"^\s*\d+\s+[A-Z_]+\s+\d+\s+\d+(\s+\S+)+\s*$")


def looks_like(text: str) -> bool:
    lines = [line for line in text.splitlines() if line.strip() and not line.lstrip().startswith("#")]
    return bool(lines) and all(_LINE.match(line) for line in lines)


def read(text: str, path: str | Path, choice: str | None = None) -> Imported:
    rows = [
        (number, line.split())
        for number, line in enumerate(text.splitlines(), 1)
        if line.strip() and not line.lstrip().startswith("#")
    ]
    if not rows:
        raise PanomapError("no camera line (CAMERA_ID MODEL WIDTH HEIGHT PARAMS[])", path)
    ids = [fields[0] for _, fields in rows]
    pick = choice if choice is not None else ids[0]
    if pick not in ids:
        raise PanomapError(f"no camera id {pick} (it has {', '.join(ids)})", path)
    number, fields = rows[ids.index(pick)]
    if len(fields) < 4:
        raise PanomapError(f"line {number}: expected CAMERA_ID MODEL WIDTH HEIGHT PARAMS[]", path)
    model = fields[1]
    if model.isdigit():
        raise PanomapError(
            f"line {number}: model {model} is a numeric id; write the model's name (ids differ between versions)",
            path,
        )
    if model not in PARAMETER_COUNTS:
        raise PanomapError(f"line {number}: model {model} is not one of {', '.join(PARAMETER_COUNTS)}", path)
    try:
        width, height = float(fields[2]), float(fields[3])
        params = [float(x) for x in fields[4:]]
    except ValueError:
        raise PanomapError(f"line {number}: the size and parameters must be numbers", path) from None
    if len(params) != PARAMETER_COUNTS[model]:
        raise PanomapError(
            f"line {number}: {model} takes {PARAMETER_COUNTS[model]} parameters, the line has {len(params)}", path
        )
    for index, value in enumerate(params):
        check_number(value, f"line {number}: parameter {index + 1}", path)
    size = image_size_of(width, height, f"line {number}: the size", path)
    return Imported(_model(model, params, path), "colmap", size, pick, COLMAP_PIXEL_SHIFT)


def _model(model: str, p: list[float], path: str | Path) -> ExternalCamera:
    s = COLMAP_PIXEL_SHIFT
    if model in ("SIMPLE_RADIAL_FISHEYE", "RADIAL_FISHEYE"):
        f, cx, cy, *k = p
        return built(ColmapRadialFisheye, path, f, cx + s, cy + s, *k)
    fx, fy, cx, cy, *rest = p
    cx, cy = cx + s, cy + s
    if model == "OPENCV_FISHEYE":
        return built(OpenCVFisheye, path, fx, fy, cx, cy, *rest)
    if model == "FOV":
        return built(ColmapFOV, path, fx, fy, cx, cy, *rest)
    if model == "THIN_PRISM_FISHEYE":
        return built(ColmapThinPrismFisheye, path, fx, fy, cx, cy, *rest)
    if model == "EUCM":
        alpha, beta = rest
        return built(ColmapEUCM, path, alpha, beta, fx, fy, cx, cy)
    return built(PinholeRadtan, path, fx, fy, cx, cy, *rest)
