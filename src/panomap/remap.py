"""Applying a map to images: build once, apply to every frame.

Convention: a map is (H, W, 2) float32 of source (u, v) per output pixel, the
centre of the top-left source pixel at (0, 0) (``cv2.remap``'s convention),
NaN where there is no source. Output pixels without a source get the fill
value (default black, alpha 0 where the image has an alpha channel).
"""

from __future__ import annotations

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
        if self.interpolation not in INTERPOLATIONS:
            raise PanomapError(f"interpolation must be nearest, linear or cubic, not {self.interpolation!r}")
        map_uv = np.asarray(self.map_uv, dtype=np.float32)
        if map_uv.ndim != 3 or map_uv.shape[2] != 2:
            raise PanomapError(f"a map must have shape (H, W, 2), not {map_uv.shape}")
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
        if out is not None:
            channels = 1 if image.ndim == 2 else image.shape[2]
            width, height = self.output_size
            expected = (height, width) if channels == 1 and out.ndim == 2 else (height, width, channels)
            if out.shape != expected or out.dtype != image.dtype:
                raise PanomapError(f"the output must be {expected} {image.dtype}, not {out.shape} {out.dtype}")
            written = cv2.remap(image, self._map1, map2, interpolation, dst=out, borderMode=cv2.BORDER_REPLICATE)
            if not np.shares_memory(written, out):  # (never seen; a guard against a binding that copies)
                out[...] = written.reshape(out.shape)
        else:
            out = cv2.remap(image, self._map1, map2, interpolation, borderMode=cv2.BORDER_REPLICATE)
            if image.ndim == 3 and out.ndim == 2:
                out = out[..., None]
        rows, cols = self._no_source
        if rows.size:
            channels = 1 if out.ndim == 2 else out.shape[2]
            fill = self.fill if isinstance(self.fill, tuple) else (self.fill,) * channels
            out[rows, cols] = fill[0] if out.ndim == 2 else fill[:channels]
        return out
