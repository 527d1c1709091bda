"""Frames through a view's map: plane by plane in the decoder's YUV format, or once as BGR.

Convention: the luma plane takes the view's map; each chroma plane the same map sampled at
the chroma sample centres (the mean of each 2 x 2 or 2 x 1 block of map entries, scaled to the
plane; chroma taken as centred between the luma samples).
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from typing import Any

import av
import cv2
import numpy as np
from numpy.typing import NDArray

from ..errors import PanomapError
from ..remap import Remapper

# OpenCV threads for the remap while a video runs. The decoder's and encoders' threads already
# keep every core busy; OpenCV's pool would only add wake-ups (less CPU per frame on one thread,
# measured with bench/bench_video.py).
REMAP_THREADS = 1
# Planar formats remapped plane by plane: log2 chroma subsampling (x, y), and the fill of each plane.
PLANAR_FORMATS: dict[str, tuple[int, int, tuple[int, ...]]] = {
    "yuv420p": (1, 1, (16, 128, 128)),
    "yuvj420p": (1, 1, (0, 128, 128)),
    "yuv422p": (1, 0, (16, 128, 128)),
    "yuvj422p": (1, 0, (0, 128, 128)),
    "yuv444p": (0, 0, (16, 128, 128)),
    "yuvj444p": (0, 0, (0, 128, 128)),
    "gray": (0, 0, (0,)),
}
BGR = "bgr24"


def _chroma_map(map_uv: NDArray[np.float32], sub_x: int, sub_y: int) -> NDArray[np.float32]:
    """The map of a chroma plane subsampled by 2**sub_x, 2**sub_y; shape (ceil(H/sy), ceil(W/sx), 2).

    Each chroma sample's entry is the mean of the luma entries it covers (NaN
    if any is), converted to chroma-plane coordinates: ``(u + 0.5)/sx - 0.5``.
    """
    sx, sy = 1 << sub_x, 1 << sub_y
    height, width = map_uv.shape[:2]
    padded = np.ascontiguousarray(map_uv, dtype=np.float32)
    if height % sy or width % sx:
        padded = np.pad(padded, ((0, -height % sy), (0, -width % sx), (0, 0)), mode="edge")
    # Each entry (u, v) read as one complex64 (u + iv): a complex sum is the two float32 sums, and NumPy's strided
    # loops then run along rows, not over pairs (4x faster on a 3840 x 1920 map).
    pairs = padded.view(np.complex64)[..., 0]
    # (summed from the first entry in the order (0, 0), (0, 1), (1, 0), (1, 1))
    sums = np.array(pairs[::sy, ::sx])
    for dy in range(sy):
        for dx in range(sx):
            if dy or dx:
                sums += pairs[dy::sy, dx::sx]
    blocks = sums.view(np.float32).reshape(*sums.shape, 2)
    # (mean + 0.5) / s - 0.5, per axis (one scalar where both axes are subsampled alike: the same float32 steps)
    scale = np.array([1 / (sx * sx * sy), 1 / (sy * sx * sy)], dtype=np.float32)
    shift = np.array([0.5 / sx - 0.5, 0.5 / sy - 0.5], dtype=np.float32)
    if sx == sy:
        blocks *= scale[0]
        blocks += shift[0]
    else:
        blocks *= scale
        blocks += shift
    return blocks


class FrameRemapper:
    """One view's maps for frames of one size and pixel format; call it on a decoded frame.

    Parameters
    ----------
    map_uv : (H, W, 2) float32 ndarray
        The view's map (source u, v per output pixel; NaN where none).
    source_size : (width, height)
        The frames' size.
    work_format : str
        A planar format of :data:`PLANAR_FORMATS` (remapped plane by plane)
        or ``bgr24`` (remapped as a still image is).
    interpolation : {"nearest", "linear", "cubic"}
    fixed_point : bool
        Keep the maps in OpenCV's fixed-point form (see :class:`Remapper`): a
        third less memory, positions rounded to 1/32 px, and on OpenCV 5.0
        slower on one-channel planes (``bench/bench_video.py`` measures it),
        hence off by default.
    """

    def __init__(
        self,
        map_uv: NDArray[np.float32],
        source_size: tuple[int, int],
        work_format: str,
        interpolation: str = "linear",
        fixed_point: bool = False,
    ) -> None:
        self.work_format = work_format
        self.output_size = (map_uv.shape[1], map_uv.shape[0])
        width, height = source_size
        if work_format == BGR:
            self._planes = [Remapper(map_uv, source_size, interpolation, 0.0, fixed_point)]
            return
        check_output_size(work_format, self.output_size)
        sub_x, sub_y, fills = PLANAR_FORMATS[work_format]
        chroma = _chroma_map(map_uv, sub_x, sub_y) if len(fills) > 1 else map_uv
        chroma_size = (-(-width >> sub_x), -(-height >> sub_y))
        self._planes = [
            Remapper(map_uv, source_size, interpolation, float(fills[0]), fixed_point),
            *(Remapper(chroma, chroma_size, interpolation, float(fill), fixed_point) for fill in fills[1:]),
        ]

    def __call__(self, frame: Any) -> Any:
        """Remap one decoded ``av.VideoFrame`` (already in the work format); a new frame out."""
        width, height = self.output_size
        if self.work_format == BGR:
            out = av.VideoFrame.from_ndarray(self._planes[0](frame.to_ndarray(format=BGR)), format=BGR)
        else:
            out = av.VideoFrame(width, height, self.work_format)
            for remapper, source, target in zip(self._planes, frame.planes, out.planes, strict=True):
                remapper(_plane_array(source), out=_plane_array(target))
        out.pts = frame.pts
        if frame.time_base is not None:
            out.time_base = frame.time_base
        return out


def check_output_size(work_format: str, size: tuple[int, int]) -> None:
    """Refuse a view size (W, H) that the work format's chroma subsampling does not divide."""
    if work_format not in PLANAR_FORMATS:
        return
    sub_x, sub_y, _ = PLANAR_FORMATS[work_format]
    width, height = size
    if width % (1 << sub_x) or height % (1 << sub_y):
        even = (max(1 << sub_x, width >> sub_x << sub_x), max(1 << sub_y, height >> sub_y << sub_y))
        raise PanomapError(
            f"{work_format} needs an output size divisible by {1 << sub_x} x {1 << sub_y}, "
            f"not {width} x {height}: give the view a size such as size={even[0]}x{even[1]}"
        )


def _plane_array(plane: Any) -> NDArray[np.uint8]:
    """An (h, w) uint8 view of a frame plane (rows padded to its line size in memory)."""
    return np.frombuffer(plane, np.uint8).reshape(plane.height, plane.line_size)[:, : plane.width]


def work_format(input_format: str, output_format: str) -> str:
    """The format frames are remapped in: the decoder's own where it and the output are YUV."""
    output_is_rgb = av.VideoFormat(output_format).is_rgb
    if not output_is_rgb and input_format in PLANAR_FORMATS:
        return input_format
    if not output_is_rgb and output_format in PLANAR_FORMATS:
        return output_format
    return BGR


@contextlib.contextmanager
def opencv_threads(count: int) -> Iterator[None]:
    """Run the block with OpenCV using ``count`` threads, then give back the caller's setting."""
    before = cv2.getNumThreads()
    cv2.setNumThreads(count)
    try:
        yield
    finally:
        cv2.setNumThreads(before)
