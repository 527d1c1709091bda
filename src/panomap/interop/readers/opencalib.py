"""OpenCalib's (PJLab SensorsCalibration) camera intrinsic JSON, OCam kind: ``surround-camera/manual_calib``.

One object, ``"<name>_camera-intrinsic"``, whose ``param`` holds ``cam_K`` {``data``: [[c, d, u0],
[e, 1, v0], [0, 0, 1]]}, ``cam_dist`` {``cols``, ``data``: [[p0, ..., p(n-1)]]: OCamCalib's inverse
polynomial, ascending} and ``img_dist_w``, ``img_dist_h`` (the image size). The tool's
``LoadIntrinsic`` reads the first object, ``cam_K.data`` and ``cols`` values of ``cam_dist.data[0]``; this
reader asks for exactly one object and ``cols`` equal to the values listed (where ``cols`` is given), so
that what it reads is what the tool reads, and for the image size (the tool does not read it; the
polynomial holds within the image, and the model's range stops at its farthest corner).

The same file layout holds the tool's pinhole and ``cv::fisheye`` cameras (``run_avm``'s model 2 and 0,
chosen on its command line, not in the file): their ``cam_K`` is [[fx, 0, cx], [0, fy, cy], [0, 0, 1]].
Only the OCam kind (model 1) is read: a ``cam_K.data[1][1]`` other than 1 is refused naming it. The
model and the tool's equations: :mod:`panomap.interop.models.ocam_inverse` (pixels from 0 at the
top-left pixel's centre, as ``cv::remap`` samples: nothing is shifted). An extrinsic file
(``sensor_calib``) is recognised and refused with a pointer to its intrinsic file. The file is read
within the bounds of :mod:`.json_text`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ...errors import PanomapError
from ..models.ocam_inverse import OCamInverse
from .base import Imported, built, image_size_of, member, typed_number
from .json_text import load_json
from .yaml_text import brief

# A polynomial's radius at the axis (px) beyond which it is no inverse of a central camera's projection: the
# rays next to the axis would land on a circle this far from the centre (OCamCalib fits it within 0.01 px).
MAX_AXIS_RADIUS_PX = 0.5


def looks_like(text: str) -> bool:
    """Whether ``text`` reads as an OpenCalib parameter file: a JSON object with ``param_type`` and ``param``
    and ``cam_K`` or ``cam_dist`` (an intrinsic) or ``sensor_calib`` (an extrinsic, refused by :func:`read`),
    found without parsing."""
    if not text.lstrip("\ufeff \t\r\n").startswith("{") or not all(f'"{k}"' in text for k in ("param_type", "param")):
        return False
    return any(f'"{k}"' in text for k in ("cam_K", "cam_dist", "sensor_calib"))


def read(text: str, path: str | Path, choice: str | None = None) -> Imported:
    data = load_json(text, path)
    if not isinstance(data, dict) or len(data) != 1:
        count = f"{len(data)} objects" if isinstance(data, dict) else brief(data)
        raise PanomapError(f"not an OpenCalib intrinsic: it holds one object (its sensor's), this one {count}", path)
    ((name, entry),) = data.items()
    if not isinstance(entry, dict):
        raise PanomapError(f"{name} is {brief(entry)}, not an object", path)
    if "param" not in entry and "param_type" not in entry:
        raise PanomapError(f"not an OpenCalib intrinsic: its one object, {name}, has no param", path)
    param = member(entry, "param", path, dict, "an object", name)
    if "sensor_calib" in param and "cam_K" not in param:
        raise PanomapError(f"{name} is an extrinsic (a pose, sensor_calib): import its intrinsic file", path)
    k = _matrix(member(param, "cam_K", path, dict, "an object", f"{name}.param"), f"{name}.param.cam_K", path)
    where = f"{name}.param.cam_K.data"
    if k[2] != [0.0, 0.0, 1.0] or k[1][1] != 1:
        raise PanomapError(
            f"{where} is {brief(k)}, not [[c, d, u0], [e, 1, v0], [0, 0, 1]]: only OCam calibrations are read "
            "(not a pinhole's or cv::fisheye's)",
            path,
        )
    invpol = _coefficients(
        member(param, "cam_dist", path, dict, "an object", f"{name}.param"), f"{name}.param.cam_dist", path
    )
    (c, d, u0), (e, _, v0) = k[0], k[1]
    for key in ("img_dist_w", "img_dist_h"):
        if key not in param:
            raise PanomapError(f"{name}.param.{key} is missing (the image size)", path)
    width, height = (typed_number(param[f"img_dist_{key}"], f"{name}.param.img_dist_{key}", path) for key in "wh")
    w, h = image_size_of(width, height, f"{name}.param.img_dist_w/h", path)
    model = built(OCamInverse, path, tuple(invpol), u0, v0, c, d, e, w, h)
    assert isinstance(model, OCamInverse)
    _check_range(model, f"{name}.param.cam_dist", path)
    return Imported(model, "opencalib", (w, h), notes=(f"OpenCalib OCam intrinsic {name!r}",))


def _check_range(model: OCamInverse, where: str, path: str | Path) -> None:
    """Refuse what is no camera's: an affine that mirrors the image (OCamCalib's is close to the identity), a
    centre outside the image, a polynomial whose axis lands off the centre or that turns back inside the image."""
    det = model.c - model.d * model.e
    if det <= 0:
        raise PanomapError(
            f"the affine [[c, d], [e, 1]] of cam_K has determinant {det:.3g}: it mirrors the image (OCamCalib's is "
            "close to the identity)",
            path,
        )
    if abs(model.axis_radius_px) > MAX_AXIS_RADIUS_PX:
        raise PanomapError(
            f"{where}'s polynomial puts the optical axis {model.axis_radius_px:.2f} px from the centre (at most "
            f"{MAX_AXIS_RADIUS_PX:g}): not an inverse polynomial",
            path,
        )
    u0, v0 = model.principal_point
    inscribed = min(u0 + 0.5, v0 + 0.5, model.width - 0.5 - u0, model.height - 0.5 - v0)
    if inscribed <= 0:
        raise PanomapError(
            f"the centre (u0, v0) = ({u0:g}, {v0:g}) lies outside the {model.width} x {model.height} image", path
        )
    if model.reach_px < inscribed:
        raise PanomapError(
            f"{where}'s polynomial turns back at a radius of {model.reach_px:.1f} px, inside the image "
            f"({inscribed:.1f} px from the centre to its nearest edge)",
            path,
        )


def _rows(node: dict[str, Any], where: str, path: str | Path) -> list[Any]:
    """``node["data"]``: a list of rows (lists)."""
    if "data" not in node:
        raise PanomapError(f"{where}.data is missing", path)
    rows = node["data"]
    if not isinstance(rows, list) or not rows or not all(isinstance(row, list) for row in rows):
        raise PanomapError(f"{where}.data is {brief(rows)}, not a list of rows", path)
    return rows


def _matrix(node: dict[str, Any], where: str, path: str | Path) -> list[list[float]]:
    rows = _rows(node, where, path)
    if len(rows) != 3 or any(len(row) != 3 for row in rows):
        raise PanomapError(f"{where}.data is {brief(rows)}, not 3 rows of 3 numbers", path)
    return [[typed_number(x, f"{where}.data[{i}][{j}]", path) for j, x in enumerate(row)] for i, row in enumerate(rows)]


def _coefficients(node: dict[str, Any], where: str, path: str | Path) -> list[float]:
    """The one row of ``node["data"]``, as long as ``node["cols"]`` says where it says."""
    rows = _rows(node, where, path)
    if len(rows) != 1:
        raise PanomapError(f"{where}.data has {len(rows)} rows; the polynomial is one row", path)
    values = [typed_number(x, f"{where}.data[0][{i}]", path) for i, x in enumerate(rows[0])]
    if "cols" in node:
        cols = typed_number(node["cols"], f"{where}.cols", path)
        if cols != len(values):
            raise PanomapError(
                f"{where}.cols is {cols:g} and data[0] lists {len(values)} coefficients: the tool reads cols of them",
                path,
            )
    return values
