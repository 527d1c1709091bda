"""OpenCV FileStorage files (YAML or JSON) of ``cv::fisheye`` (K, D) and ``cv::omnidir`` (K, D, xi).

Read with OpenCV's own ``cv2.FileStorage``. The key spellings read, first match wins:

- camera matrix: ``K``, ``camera_matrix`` (OpenCV's calibration samples and its omnidir sample),
  ``cameraMatrix``; 3 x 3, ``[[fx, skew, cx], [0, fy, cy], [0, 0, 1]]``;
- distortion: ``D``, ``distortion_coefficients`` (the samples), ``dist_coeffs``, ``distCoeffs``;
- ``xi`` (omnidir; a number or a 1 x 1 matrix): its presence makes the file an omnidir camera;
- size: ``image_width`` and ``image_height`` (the samples), or ``image_size`` / ``imageSize`` [w, h];
- ``fisheye_model`` (the calibration tutorial's flag): 1 for cv::fisheye, 0 for the plain pinhole.

Without ``xi``: 4 coefficients are cv::fisheye's k1..k4 (unless ``fisheye_model`` is 0); a plain
pinhole's k1 k2 p1 p2 [k3] is read as pinhole-radtan when k3 (if present) is 0. With ``xi``: D is
k1 k2 p1 p2 and K's skew is kept. OpenCV's pixels are panomap's: nothing is shifted.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import cv2
import numpy as np

from ...errors import PanomapError
from ..models.kannala_brandt import OpenCVFisheye
from ..models.mei import Mei
from ..models.pinhole_radtan import PinholeRadtan
from .base import Imported, built, image_size_of

MATRIX_KEYS = ("K", "camera_matrix", "cameraMatrix")
DISTORTION_KEYS = ("D", "distortion_coefficients", "dist_coeffs", "distCoeffs")


def looks_like(text: str) -> bool:
    return "opencv-matrix" in text


def _node(storage: Any, keys: tuple[str, ...]) -> tuple[str, Any] | None:
    for key in keys:
        node = storage.getNode(key)
        if not node.empty():
            return key, node
    return None


def _values(node: Any, key: str, path: str | Path) -> np.ndarray:
    if node.isReal() or node.isInt():
        return np.array([node.real()])
    matrix = node.mat()
    if matrix is None:
        if node.isSeq():
            return np.array([node.at(i).real() for i in range(node.size())])
        raise PanomapError(f"{key} is not a matrix or a number", path)
    return np.asarray(matrix, dtype=np.float64).ravel()


def read(text: str, path: str | Path, choice: str | None = None) -> Imported:
    try:
        storage = cv2.FileStorage(text, cv2.FILE_STORAGE_READ | cv2.FILE_STORAGE_MEMORY)
    except cv2.error:
        raise PanomapError("not a readable OpenCV FileStorage file (YAML or JSON)", path) from None
    if not storage.isOpened():
        raise PanomapError("not a readable OpenCV FileStorage file (YAML or JSON)", path)
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
    if not np.all(np.isfinite(np.concatenate([k, d]))):
        raise PanomapError(f"{key} or {d_key} has a non-finite value", path)
    size = _size(storage, path)
    xi_node = storage.getNode("xi")
    if not xi_node.empty():
        xi = _values(xi_node, "xi", path)
        if xi.size != 1:
            raise PanomapError(f"xi has {xi.size} values, expected 1", path)
        if d.size != 4:
            raise PanomapError(f"{d_key} has {d.size} values, expected 4 (k1 k2 p1 p2) for cv::omnidir", path)
        return Imported(built(Mei, path, float(xi[0]), fx, fy, cx, cy, *d, skew), "opencv-omnidir", size)
    if skew != 0:
        raise PanomapError(f"{key} has a skew ({skew:g}); cv::fisheye's alpha is not read", path)
    flag = storage.getNode("fisheye_model")
    fisheye = d.size == 4 if flag.empty() else bool(flag.real())
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
    width, height = storage.getNode("image_width"), storage.getNode("image_height")
    if not width.empty() and not height.empty():
        return image_size_of(width.real(), height.real(), "image_width, image_height", path)
    for key in ("image_size", "imageSize"):
        node = storage.getNode(key)
        if not node.empty():
            values = _values(node, key, path)
            if values.size != 2:
                raise PanomapError(f"{key} has {values.size} values, expected 2 (width height)", path)
            return image_size_of(values[0], values[1], key, path)
    return None
