"""What a calibration reader gives back, and the checks every reader shares.

A reader is a function ``read(text, path, choice) -> Imported``: ``choice`` is the camera to take
(a Kalibr camchain's name, a COLMAP camera id; None for the first). Problems raise
:class:`panomap.errors.PanomapError` naming the file and the field.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ...errors import PanomapError
from ...table.file import MAX_IMAGE_SIDE
from ...values import MAX_ABS, NotFinite, finite_number
from ..models.base import ExternalCamera
from .yaml_text import brief


@dataclass(frozen=True)
class RigPose:
    """A camera's pose in its rig, as the file gives it (Basalt's ``T_imu_cam``: camera frame to the IMU's).

    ``translation_m`` (px, py, pz) is the camera's centre in the IMU frame (m); ``quaternion_xyzw`` the
    rotation of camera to IMU coordinates, a unit quaternion (qx, qy, qz, qw). Kept, not yet used.
    """

    camera: str
    translation_m: tuple[float, float, float]
    quaternion_xyzw: tuple[float, float, float, float]


@dataclass(frozen=True)
class Imported:
    """A calibration as read: the model, the format it came in, and what else the file says.

    ``image_size`` is (width, height) px when the file gives it; ``camera`` names the camera picked
    in a file of several (None otherwise); ``pixel_shift_px`` is what was added to the file's pixel
    coordinates to reach panomap's (-0.5 for COLMAP); ``rig_poses`` every camera's pose in a rig, in the
    file's order, where the file gives them (Basalt's); ``notes`` what the reader decided that the user
    should hear.
    """

    model: ExternalCamera
    format: str
    image_size: tuple[int, int] | None
    camera: str | None = None
    pixel_shift_px: float = 0.0
    notes: tuple[str, ...] = field(default_factory=tuple)
    rig_poses: tuple[RigPose, ...] = field(default_factory=tuple)


# The most values a list of a calibration file holds (OCam's polynomials: about 20).
MAX_LIST = 64
# The largest image a calibration may be for: the largest panomap reads (io.images.MAX_IMAGE_PIXELS, a
# layer above this one; tests/test_interop_bounds.py checks that the two agree).
MAX_IMAGE_PIXELS = 16384 * 16384


def member(data: dict[str, Any], key: str, path: str | Path, kind: type, noun: str, where: str = "") -> Any:
    """``data[key]``, refused where it is missing or not of ``kind`` (``noun`` names one: "an object", "a list"),
    the field named ``where.key`` (``key`` alone without ``where``)."""
    field_name = f"{where}.{key}" if where else key
    if key not in data:
        raise PanomapError(f"{field_name} is missing", path)
    value = data[key]
    if not isinstance(value, kind):
        raise PanomapError(f"{field_name} is {brief(value)}, not {noun}", path)
    return value


def number(value: Any, where: str, path: str | Path, text: bool = True) -> float:
    """``value`` (a number, or its text unless ``text`` is False: JSON's and YAML's typed numbers) as a
    finite float at most ``MAX_ABS`` (1e9) in size: no calibration parameter, size or radius is larger,
    and arithmetic on larger ones overflows."""
    if not text and (isinstance(value, bool) or not isinstance(value, (int, float))):
        raise PanomapError(f"{where} is {brief(value)}, not a number", path)
    try:
        return finite_number(value, bools=False)
    except NotFinite as exc:
        what = "not a number" if not exc.number else f"not a finite number of at most {MAX_ABS:g} in size"
        raise PanomapError(f"{where} is {brief(value)}, {what}", path) from None


def typed_number(value: Any, where: str, path: str | Path) -> float:
    """:func:`number` of a value a JSON or YAML file writes as a number (text such as ``"250"`` is refused,
    as BoofCV's, Basalt's and gyroflow's own loaders refuse it)."""
    return number(value, where, path, text=False)


# A number as YAML 1.2 writes it: YAML 1.1 (PyYAML) reads ``1e-5`` (no dot) and ``1E+3`` as text, which
# Kalibr's own writer (and any YAML 1.2 tool) gives for small distortion coefficients.
_NUMBER_TEXT = re.compile(r"[-+]?(\.[0-9]+|[0-9]+(\.[0-9]*)?)([eE][-+]?[0-9]+)?")


def numbers(value: Any, where: str, path: str | Path, count: int | tuple[int, ...] | None = None) -> list[float]:
    """``value`` as a list of finite numbers (each as :func:`number`; a number's text as YAML 1.2 writes it,
    ``1e-5``, which YAML 1.1 reads as text, counts), ``count`` long (or one of the counts) when given."""

    def is_number(x: Any) -> bool:
        if isinstance(x, str):
            return len(x) <= 64 and _NUMBER_TEXT.fullmatch(x.strip()) is not None
        return isinstance(x, (int, float)) and not isinstance(x, bool)

    if not isinstance(value, (list, tuple)) or len(value) > MAX_LIST or not all(is_number(x) for x in value):
        raise PanomapError(f"{where} is {brief(value)}, not a list of numbers", path)
    values = [number(x, f"{where}[{i}]", path) for i, x in enumerate(value)]
    counts = (count,) if isinstance(count, int) else count
    if counts is not None and len(values) not in counts:
        wanted = " or ".join(str(c) for c in counts)
        raise PanomapError(f"{where} has {len(values)} values, expected {wanted}", path)
    return values


def image_size_of(width: float, height: float, where: str, path: str | Path) -> tuple[int, int]:
    """(width, height) px as positive whole numbers, within the images panomap reads (MAX_IMAGE_PIXELS) and each
    side at most a table file's limit (:data:`panomap.table.file.MAX_IMAGE_SIDE`: a table for a larger image
    could not be loaded)."""
    if not all(math.isfinite(x) and x == int(x) and x > 0 for x in (width, height)):
        raise PanomapError(f"{where} is {width:g} x {height:g}, not a positive whole size", path)
    if max(width, height) > MAX_IMAGE_SIDE:
        raise PanomapError(
            f"{where} is {width:g} x {height:g}: larger than any image (at most {MAX_IMAGE_SIDE} px a side)", path
        )
    if width * height > MAX_IMAGE_PIXELS:
        raise PanomapError(
            f"{where} is {width:g} x {height:g}, larger than the images panomap reads ({MAX_IMAGE_PIXELS} pixels)", path
        )
    return int(width), int(height)


def built(cls: type[ExternalCamera], path: str | Path, *args: Any) -> ExternalCamera:
    """``cls(*args)``, its parameter checks' errors naming the file."""
    try:
        return cls(*args)
    except PanomapError as exc:
        raise PanomapError(exc.detail, path) from None
