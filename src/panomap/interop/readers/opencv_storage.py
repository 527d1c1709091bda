"""OpenCV FileStorage files (YAML or JSON) of ``cv::fisheye`` (K, D) and ``cv::omnidir`` (K, D, xi).

Read with OpenCV's own ``cv2.FileStorage``. The key spellings read, first match wins:

- camera matrix: ``K``, ``camera_matrix`` (OpenCV's calibration samples and its omnidir sample),
  ``cameraMatrix``, ``Camera_Matrix`` (the calibration tutorial's ``out_camera_data``), ``M``,
  ``camera_matrix_1`` (the omnidir stereo sample: its first camera); 3 x 3,
  ``[[fx, skew, cx], [0, fy, cy], [0, 0, 1]]``;
- distortion: ``D``, ``distortion_coefficients`` (the samples), ``dist_coeffs``, ``distCoeffs``,
  ``Distortion_Coefficients``, ``distortion_coefficients_1``;
- ``xi`` or ``xi_1`` (omnidir): its presence makes the file an omnidir camera;
- size: ``image_width`` and ``image_height`` (the samples), ``image_Width`` and ``image_Height`` (the
  tutorial), or ``image_size`` / ``imageSize`` [w, h];
- ``fisheye_model`` (the calibration tutorial's flag): 1 for cv::fisheye, 0 for the plain pinhole.

Each value is an ``opencv-matrix``, a plain list of numbers, or a number (``xi``). Without ``xi``: 4
coefficients are cv::fisheye's k1..k4 (unless ``fisheye_model`` is 0); a plain pinhole's k1 k2 p1 p2
[k3] is read as pinhole-radtan when k3 (if present) is 0. With ``xi``: D is k1 k2 p1 p2 and K's skew is
kept. OpenCV's pixels are panomap's: nothing is shifted. Every number must be finite and at most 1e9 in
size (OpenCV reads an integer too long for 64 bits as the largest one).
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from ...errors import PanomapError
from ..models.kannala_brandt import OpenCVFisheye
from ..models.mei import Mei
from ..models.pinhole_radtan import PinholeRadtan
from .base import MAX_LIST, Imported, built, image_size_of, number
from .yaml_text import MAX_CHARS

MATRIX_KEYS = ("K", "camera_matrix", "cameraMatrix", "Camera_Matrix", "M", "camera_matrix_1")
DISTORTION_KEYS = (
    "D",
    "distortion_coefficients",
    "dist_coeffs",
    "distCoeffs",
    "Distortion_Coefficients",
    "distortion_coefficients_1",
)
XI_KEYS = ("xi", "xi_1")
SIZE_KEYS = (("image_width", "image_height"), ("image_Width", "image_Height"))
# A file of OpenCV's (its "%YAML:1.0" first line, or JSON) with a camera matrix key at the top.
_MATRIX_LINE = re.compile(r'^[ \t{]*"?(?:' + "|".join(MATRIX_KEYS) + r')"?[ \t]*:', re.MULTILINE)


def looks_like(text: str) -> bool:
    if "opencv-matrix" in text:
        return True
    head = text.lstrip("\ufeff \t\r\n")
    opencv_file = head.startswith("%YAML:") or head.startswith("{")
    return opencv_file and "camera_model" not in text and _MATRIX_LINE.search(text) is not None


def _node(storage: Any, keys: tuple[str, ...]) -> tuple[str, Any] | None:
    for key in keys:
        node = storage.getNode(key)
        if not node.empty():
            return key, node
    return None


def _values(node: Any, key: str, path: str | Path) -> np.ndarray:
    """The numbers of ``node``: a number, a plain list of numbers or an ``opencv-matrix``; each finite
    and at most 1e9 in size."""
    if node.isReal() or node.isInt():
        values = [node.real()]
    elif node.isSeq():
        if node.size() > MAX_LIST:
            raise PanomapError(f"{key} has {node.size()} values, more than a camera has", path)
        items = [node.at(i) for i in range(node.size())]
        if not all(item.isReal() or item.isInt() for item in items):
            raise PanomapError(f"{key} is a list, but not of numbers", path)
        values = [item.real() for item in items]
    elif node.isMap() and not node.getNode("data").empty():
        matrix = node.mat()
        if matrix is None or matrix.size > MAX_LIST:
            raise PanomapError(f"{key} is not a matrix of a camera's size", path)
        values = np.asarray(matrix, dtype=np.float64).ravel().tolist()
    else:
        raise PanomapError(f"{key} is not a matrix, a list of numbers or a number", path)
    return np.array([number(v, key, path) for v in values], dtype=np.float64)


def _open(text: str, path: str | Path) -> Any:
    """The FileStorage of ``text``: OpenCV's parser fails with cv2.error, or with a SystemError (an
    exception set inside its Python binding) on some malformed or deeply nested files."""
    unreadable = "not a readable OpenCV FileStorage file (YAML or JSON)"
    if len(text) > MAX_CHARS:
        raise PanomapError(f"{len(text)} characters: more than a calibration file holds ({MAX_CHARS})", path)
    try:
        storage = cv2.FileStorage(text, cv2.FILE_STORAGE_READ | cv2.FILE_STORAGE_MEMORY)
    except (cv2.error, SystemError):
        raise PanomapError(unreadable, path) from None
    if not storage.isOpened():
        raise PanomapError(unreadable, path)
    return storage


def read(text: str, path: str | Path, choice: str | None = None) -> Imported:
    storage = _open(text, path)
    try:
        return _read(storage, path)
    except (cv2.error, SystemError):  # a node OpenCV's binding cannot convert
        raise PanomapError("a camera value OpenCV cannot read (a malformed matrix?)", path) from None


def _read(storage: Any, path: str | Path) -> Imported:
    if not storage.root().isMap():
        raise PanomapError("not a map of named values (an OpenCV FileStorage file holds K, D, ...)", path)
    found_k = _node(storage, MATRIX_KEYS)
    if found_k is None:
        raise PanomapError(f"the camera matrix is missing (looked for {', '.join(MATRIX_KEYS)})", path)
    key, node = found_k
    k = _values(node, key, path)
    if k.size != 9:
        raise PanomapError(f"{key} has {k.size} values, expected 9 (3 x 3)", path)
    fx, skew, cx, _, fy, cy = k[:6]
    found_d = _node(storage, DISTORTION_KEYS)
    if found_d is None:
        raise PanomapError(f"the distortion is missing (looked for {', '.join(DISTORTION_KEYS)})", path)
    d_key, d_node = found_d
    d = _values(d_node, d_key, path)
    size = _size(storage, path)
    found_xi = _node(storage, XI_KEYS)
    if found_xi is not None:
        xi_key, xi_node = found_xi
        xi = _values(xi_node, xi_key, path)
        if xi.size != 1:
            raise PanomapError(f"{xi_key} has {xi.size} values, expected 1", path)
        if d.size != 4:
            raise PanomapError(f"{d_key} has {d.size} values, expected 4 (k1 k2 p1 p2) for cv::omnidir", path)
        return Imported(built(Mei, path, float(xi[0]), fx, fy, cx, cy, *d, skew), "opencv-omnidir", size)
    if skew != 0:
        raise PanomapError(f"{key} has a skew ({skew:g}); cv::fisheye's alpha is not read", path)
    flag = storage.getNode("fisheye_model")
    fisheye = d.size == 4 if flag.empty() else bool(_values(flag, "fisheye_model", path)[0])
    if fisheye:
        if d.size != 4:
            raise PanomapError(f"{d_key} has {d.size} values, expected 4 (k1 k2 k3 k4) for cv::fisheye", path)
        return Imported(built(OpenCVFisheye, path, fx, fy, cx, cy, *d), "opencv-fisheye", size)
    if d.size not in (4, 5) or (d.size == 5 and d[4] != 0):
        raise PanomapError(
            f"{d_key} has {d.size} values: a plain OpenCV camera is read with k1 k2 p1 p2 (and k3 = 0) only", path
        )
    return Imported(built(PinholeRadtan, path, fx, fy, cx, cy, *d[:4]), "opencv-pinhole", size)


def _size(storage: Any, path: str | Path) -> tuple[int, int] | None:
    for width_key, height_key in SIZE_KEYS:
        width, height = storage.getNode(width_key), storage.getNode(height_key)
        if not width.empty() and not height.empty():
            w, h = _values(width, width_key, path), _values(height, height_key, path)
            if w.size != 1 or h.size != 1:
                raise PanomapError(f"{width_key} and {height_key} must be one number each", path)
            return image_size_of(w[0], h[0], f"{width_key}, {height_key}", path)
    for key in ("image_size", "imageSize"):
        node = storage.getNode(key)
        if not node.empty():
            values = _values(node, key, path)
            if values.size != 2:
                raise PanomapError(f"{key} has {values.size} values, expected 2 (width height)", path)
            return image_size_of(values[0], values[1], key, path)
    return None
