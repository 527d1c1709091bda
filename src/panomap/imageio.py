"""Reading and writing images and maps, keeping depth and channels.

Images are NumPy arrays (H, W) or (H, W, C) with C in 1, 3, 4, uint8 or
uint16, channels in OpenCV's order (BGR[A]). Every write goes through a
temporary file and a rename.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from .errors import PanomapError
from .files import write_bytes_atomic, write_with

SIXTEEN_BIT_SUFFIXES = {".png", ".tif", ".tiff", ".pgm", ".ppm", ".pnm"}
ALPHA_SUFFIXES = {".png", ".tif", ".tiff", ".webp"}


def read_image(path: str | Path) -> NDArray[Any]:
    """Read an image unchanged (depth, channels).

    Raises
    ------
    PanomapError
        Naming the file when it is missing, unreadable or of an unsupported depth.
    """
    path = Path(path)
    if not path.exists():
        raise PanomapError("no such image file", path)
    if not path.is_file():
        raise PanomapError("not a file", path)
    data = np.fromfile(path, dtype=np.uint8)
    image = cv2.imdecode(data, cv2.IMREAD_UNCHANGED) if data.size else None
    if image is None:
        raise PanomapError("cannot read it as an image (unknown format or corrupt)", path)
    if image.dtype not in (np.uint8, np.uint16):
        raise PanomapError(f"images must be 8- or 16-bit, this one is {image.dtype}", path)
    return image


def image_size(path: str | Path) -> tuple[int, int]:
    """(width, height) of an image file."""
    image = read_image(path)
    return int(image.shape[1]), int(image.shape[0])


def write_image(path: str | Path, image: NDArray[Any]) -> None:
    """Write an image, choosing the format by suffix; refuses to lose depth or alpha."""
    path = Path(path)
    suffix = path.suffix.lower()
    if image.dtype == np.uint16 and suffix not in SIXTEEN_BIT_SUFFIXES:
        raise PanomapError("16-bit images need PNG, TIFF or PNM output, not " + (suffix or "no suffix"), path)
    if image.ndim == 3 and image.shape[2] == 4 and suffix not in ALPHA_SUFFIXES:
        raise PanomapError("images with alpha need PNG, TIFF or WebP output, not " + (suffix or "no suffix"), path)
    try:
        ok, encoded = cv2.imencode(suffix or ".none", image)
    except cv2.error:
        ok = False
    if not ok:
        raise PanomapError(f"cannot write an image in the format {suffix or '(no suffix)'}", path)
    write_bytes_atomic(path, encoded.tobytes())


def save_map(path: str | Path, map_uv: NDArray[np.float32]) -> None:
    """Save a map (H, W, 2) float32 as ``.npy`` (the conventions' map file)."""
    array = np.ascontiguousarray(map_uv, dtype=np.float32)
    write_with(path, lambda handle: np.save(handle, array, allow_pickle=False))
