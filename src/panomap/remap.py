"""Applying a map to images: build once, apply to every frame.

Convention: a map is (H, W, 2) float32 of source (u, v) per output pixel, the
centre of the top-left source pixel at (0, 0) (``cv2.remap``'s convention),
NaN where there is no source. Output pixels without a source get the fill
value (default black, alpha 0 where the image has an alpha channel).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from . import inputs
from .errors import PanomapError
from .geometry import inside_image

INTERPOLATIONS = {"nearest": cv2.INTER_NEAREST, "linear": cv2.INTER_LINEAR, "cubic": cv2.INTER_CUBIC}
DTYPES = (np.uint8, np.uint16, np.float32)


@dataclass(frozen=True)
class Remapper:
    """Applies one map to any number of frames of one source size.

    Parameters
    ----------
    map_uv : (H, W, 2) float32 ndarray
        Source (u, v) per output pixel; NaN where there is no source.
    source_size : (width, height), optional
        The size frames must have (any size when omitted); map entries outside
        such a frame count as having no source.
    interpolation : {"nearest", "linear", "cubic"}
    fill : float or tuple of float
        Value of output pixels without a source.
    fixed_point : bool
        Convert the maps once with ``cv2.convertMaps`` to OpenCV's fixed-point
        form (``CV_16SC2`` plus 1/32-pixel interpolation weights): 25% less
        memory (50% for nearest), positions rounded to 1/32 px. On OpenCV 5.0
        it is faster for bilinear 3-channel frames (0.56-0.76x the time in
        ``bench/bench_views.py``), not for nearest or 1-channel ones. Default
        False: float maps, exact positions.

    Interpolation near the image edge reads replicated edge pixels
    (``BORDER_REPLICATE``), never the fill value; output pixels whose map entry
    is NaN are set to the fill value afterwards.
    """

    map_uv: NDArray[np.float32]
    source_size: tuple[int, int] | None = None
    interpolation: str = "linear"
    fill: float | tuple[float, ...] = 0.0
    fixed_point: bool = False
    _map1: NDArray[Any] = field(init=False, repr=False)
    _map2: NDArray[Any] | None = field(init=False, repr=False)
    _no_source: tuple[NDArray[np.intp], NDArray[np.intp]] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        check_interpolation(self.interpolation)
        map_uv = _checked_map(self.map_uv)
        if self.source_size is not None:
            size = inputs.whole_numbers(self.source_size, 2, "the source size (W, H)")
            if min(size) <= 0:
                raise PanomapError(f"the source size (W, H) must be positive, not {size[0]} x {size[1]}")
            object.__setattr__(self, "source_size", size)
        object.__setattr__(self, "fill", _checked_fill(self.fill))
        u, v = map_uv[..., 0], map_uv[..., 1]
        with np.errstate(invalid="ignore"):
            if self.source_size is not None:  # (comparisons with NaN are false: NaN entries drop out too)
                valid = inside_image(u, v, self.source_size)
            else:
                valid = np.isfinite(u) & np.isfinite(v)
        map_u = np.where(valid, u, np.float32(0))
        map_v = np.where(valid, v, np.float32(0))
        no_source = np.nonzero(~valid)  # (rows, cols): works on any output's strides
        map1: NDArray[Any] = map_u
        map2: NDArray[Any] | None = map_v
        if self.fixed_point:
            nearest = self.interpolation == "nearest"
            map1, map2 = cv2.convertMaps(map_u, map_v, cv2.CV_16SC2, nninterpolation=nearest)
            if nearest:
                map2 = None  # integer positions only
        for array in (map1, map2, *no_source):
            if array is not None:
                array.setflags(write=False)
        object.__setattr__(self, "_map1", map1)
        object.__setattr__(self, "_map2", map2)
        object.__setattr__(self, "_no_source", no_source)

    @property
    def output_size(self) -> tuple[int, int]:
        """(W, H) of the output."""
        height, width = self._map1.shape[:2]
        return width, height

    def __call__(self, image: NDArray[Any], out: NDArray[Any] | None = None) -> NDArray[Any]:
        """Remap one frame (H_in, W_in[, C]) with C in 1, 3, 4; same dtype and channels out.

        ``out``, optional: an (H, W[, C]) array of the image's dtype to write
        into (any strides, such as a video frame's plane); returned.
        """
        image = inputs.image(image, "the frame", tuple(np.dtype(dtype) for dtype in DTYPES))
        if self.source_size is not None and (image.shape[1], image.shape[0]) != tuple(self.source_size):
            width, height = self.source_size
            raise PanomapError(
                f"the image is {image.shape[1]} x {image.shape[0]}, the table is for {width} x {height} images"
            )
        map2: Any = self._map2  # None for fixed-point nearest: integer positions only
        interpolation = INTERPOLATIONS[self.interpolation]
        fill = _fill_for(self.fill, image)
        if out is not None:
            self._check_out(out, image)
            if _cv_writable(out) and not np.may_share_memory(out, image):
                written = cv2.remap(image, self._map1, map2, interpolation, dst=out, borderMode=cv2.BORDER_REPLICATE)
            else:  # (a layout OpenCV cannot write, such as Fortran order, or the frame itself: through a copy)
                written = cv2.remap(image, self._map1, map2, interpolation, borderMode=cv2.BORDER_REPLICATE)
            if not np.shares_memory(written, out):
                out[...] = written.reshape(out.shape)
        else:
            out = cv2.remap(image, self._map1, map2, interpolation, borderMode=cv2.BORDER_REPLICATE)
            if image.ndim == 3 and out.ndim == 2:
                out = out[..., None]
        rows, cols = self._no_source
        if rows.size:
            out[rows, cols] = fill[0] if out.ndim == 2 else fill
        return out

    def _check_out(self, out: Any, image: NDArray[Any]) -> None:
        """Refuse an ``out`` that is no writable array of the output's shape and the frame's dtype."""
        channels = 1 if image.ndim == 2 else image.shape[2]
        width, height = self.output_size
        if not isinstance(out, np.ndarray):
            raise TypeError(
                f"the output must be a NumPy array ({height}, {width}, {channels}), not {type(out).__name__}"
            )
        expected = (height, width) if channels == 1 and out.ndim == 2 else (height, width, channels)
        if out.shape != expected or out.dtype != image.dtype:
            raise PanomapError(f"the output must be {expected} {image.dtype}, not {out.shape} {out.dtype}")
        if not out.flags.writeable:
            raise PanomapError("the output array is read-only: pass a writable one (out.flags.writeable)")


def check_interpolation(interpolation: object) -> str:
    """``interpolation`` if it is one of :data:`INTERPOLATIONS` (how a picture is read between its pixels);
    PanomapError otherwise."""
    if not isinstance(interpolation, str) or interpolation not in INTERPOLATIONS:
        raise PanomapError(f"interpolation must be nearest, linear or cubic, not {interpolation!r:.40}")
    return interpolation


def _checked_map(value: Any) -> NDArray[np.float32]:
    """``value`` as an (H, W, 2) float32 map of at least one pixel; huge numbers become inf (no source)."""
    try:
        array = np.asarray(value)
    except ValueError:
        raise PanomapError("a map must have shape (H, W, 2): its rows differ in length") from None
    if array.dtype.kind not in "biuf":
        raise TypeError(f"a map must hold real numbers (u, v), not {array.dtype}")
    if array.ndim != 3 or array.shape[2] != 2:
        raise PanomapError(f"a map must have shape (H, W, 2), not {array.shape}")
    if array.shape[0] == 0 or array.shape[1] == 0:
        raise PanomapError(f"a map must have at least one pixel, not shape {array.shape}")
    with np.errstate(over="ignore"):  # (beyond float32: inf, an entry with no source)
        return np.asarray(array, dtype=np.float32)


def _checked_fill(value: Any) -> float | tuple[float, ...]:
    """``fill`` as a number or a tuple of 1 to 4 numbers (NaN allowed: float frames can hold it)."""
    many = isinstance(value, list | tuple | np.ndarray)
    items = list(np.ravel(value)) if many else [value]
    if not 1 <= len(items) <= 4 or any(
        isinstance(i, bool | str | bytes) or not isinstance(i, int | float | np.number) for i in items
    ):
        raise TypeError(f"fill must be a number or 1 to 4 numbers (one per channel), not {value!r:.40}")
    numbers = tuple(float(i) for i in items)
    return numbers if many else numbers[0]


def _fill_for(fill: float | tuple[float, ...], image: NDArray[Any]) -> tuple[float, ...]:
    """The fill, one value per channel of ``image``, checked to fit its dtype (300 does not fit uint8)."""
    channels = 1 if image.ndim == 2 else image.shape[2]
    values = fill if isinstance(fill, tuple) else (fill,) * channels
    if len(values) == 1:
        values = values * channels
    if len(values) < channels:
        raise PanomapError(f"fill has {len(values)} values, the frame {channels} channels: give 1 or {channels}")
    values = values[:channels]
    if image.dtype.kind in "iu":
        low, high = np.iinfo(image.dtype).min, np.iinfo(image.dtype).max
        if not all(math.isfinite(x) and low <= x <= high for x in values):
            shown = ", ".join(f"{x:g}" for x in values)
            raise PanomapError(f"fill {shown} does not fit a {image.dtype} frame ({low}..{high})")
    return values


def _cv_writable(out: NDArray[Any]) -> bool:
    """Whether OpenCV writes into ``out`` itself: each row's pixels and channels packed (any row stride)."""
    item = out.itemsize
    if out.ndim == 2:
        return out.strides[1] == item
    return out.strides[2] == item and out.strides[1] == out.shape[2] * item
