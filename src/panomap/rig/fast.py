"""The fast blend of a rig's view: one remap of the whole output, the overlap band blended apart.

Convention: maps as :mod:`panomap.remap` ((H, W, 2) float32 source (u, v), NaN where there is no source), each
camera's in its own *source* (its picture, or the frame holding every camera's picture); weights and gains as
:mod:`.blend`.

:class:`RigRemapper` remaps every camera over the whole output and sums them: k full remaps and k float
multiply-adds per pixel. Most of a view is seen by one camera (its weight exactly 1), so :class:`RigPlane`
remaps once, from a *buffer* holding every source and, below them, the few pixels of the overlap band already
blended:

1. the pictures are copied into the buffer (side by side, or the one frame as it is);
2. each camera's entries of the band (every output pixel that two or more cameras see, in a compact list laid
   out as rows of the buffer's width) are remapped from the buffer with that list as the map, and blended
   (weights times gains, summed in float32 in the rig's order, exactly as :class:`RigRemapper` does);
3. the blended band goes into the buffer's last rows, and one combined map (each pixel from the camera that
   sees it alone, the band pixels at their integer places in the band rows, the pixels no camera sees at a fill
   pixel) makes the whole output in one ``cv2.remap``;
4. each camera's gain, a lookup table (``cv2.LUT``), is applied to the pixels only it sees
   (``cv2.copyTo`` under its mask, within the mask's bounding box).

Each camera's entries are clamped to its source (``[0, W-1] x [0, H-1]``): for bilinear and nearest reads that is
``BORDER_REPLICATE`` exactly, so the buffer's neighbouring pictures never bleed in. Results equal
:class:`RigRemapper`'s: the same float maps, the same float32 sums, the same rounding (``tests/test_rig_video.py``
checks it within 1 grey level; measured 0). Cubic reads 4 x 4 pixels, which the clamp does not make exact: it
is refused here (:class:`RigRemapper` takes it).

The maps stay float32: OpenCV 5.1 remaps from them with its vectorised float kernels, and fixed-point maps
(``cv2.convertMaps`` to ``CV_16SC2``, converted once) went through its older path: 1.4-1.5 x slower for the
3840 x 1920 luma of a dual fisheye's equirect (20.7 ms against 14.0 ms a frame, one thread), besides their 1/32 px
steps.
"""

from __future__ import annotations

import copy
from collections.abc import Sequence
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from ..errors import PanomapError
from ..geometry import inside_image
from ..remap import INTERPOLATIONS
from .blend import RigRemapper, overlap_gains
from .seams import SeamWeights

# OpenCV's remap takes sources and maps of fewer rows and columns than this.
REMAP_LIMIT = 32767
# The buffer's pictures are laid out in rows at most this wide (px).
BUFFER_WIDTH = 16384


class RigPlane:
    """One plane (or image) of a rig's view: the maps, weights and buffer of the fast blend (module docstring).

    Parameters
    ----------
    maps : list of (H, W, 2) float32
        Each camera's map in its source's pixels (NaN where it does not see).
    seams : SeamWeights
        Each camera's weight (:func:`.seams.seam_weights`): the camera that takes each pixel alone, and the band
        where several do.
    sources : list of (width, height)
        The pictures given to each call, in order (one frame holding them all, or one per camera).
    reads : list of int
        Which of ``sources`` each camera reads.
    channels : int
        The pictures' channels (1, 3 or 4).
    interpolation : {"linear", "nearest"}
    fill : float
        The value of pixels no camera sees.
    black : float
        The level gains scale from: ``out = black + g (v - black)`` (0 for BGR; 16 for limited-range luma, 128 for
        chroma).
    """

    def __init__(
        self,
        maps: Sequence[NDArray[np.float32]],
        seams: SeamWeights,
        sources: Sequence[tuple[int, int]],
        reads: Sequence[int],
        channels: int,
        interpolation: str = "linear",
        fill: float = 0.0,
        black: float = 0.0,
    ) -> None:
        if interpolation not in ("linear", "nearest"):
            raise PanomapError(
                f"the fast blend reads linear or nearest, not {interpolation!r} (a clamp is not a border for it)"
            )
        self.interpolation = INTERPOLATIONS[interpolation]
        self.channels, self.black = channels, float(black)
        self.count = len(maps)
        height, width = maps[0].shape[:2]
        if max(height, width) >= REMAP_LIMIT:
            raise PanomapError(f"a view of {width} x {height} is larger than OpenCV remaps ({REMAP_LIMIT - 1})")
        self.output_shape = (height, width) if channels == 1 else (height, width, channels)
        self.sources = [(int(size[0]), int(size[1])) for size in sources]
        places, buffer_width, pictures_height = _layout(self.sources)
        self.places = places
        band = seams.band
        self.band_size = band.size
        self.band_is_all = band.size == height * width
        band_rows = -(-(band.size + 1) // buffer_width)  # (+1: the fill pixel, after the band)
        self.band_top = pictures_height
        buffer_height = pictures_height + band_rows
        if buffer_height >= REMAP_LIMIT:
            raise PanomapError(f"the rig's pictures and overlap need {buffer_height} rows, more than OpenCV remaps")
        self._buffer_shape = (buffer_height, buffer_width) + (() if channels == 1 else (channels,))
        self._fill_at = (band.size % buffer_width, pictures_height + band.size // buffer_width)
        # The combined map: the sole camera's entry; the band's own place in the band rows; else the fill pixel.
        self.map_u = np.full((height, width), self._fill_at[0], dtype=np.float32)
        self.map_v = np.full((height, width), self._fill_at[1], dtype=np.float32)
        self.masks: list[tuple[tuple[slice, slice], NDArray[np.uint8]] | None] = []
        owners = seams.owner.view(np.uint8)
        self.shares = seams.shares()  # (each camera's share of the whole view: the gains' scale, as RigRemapper's)
        # The band: each camera's entries and weights, laid out as the band rows (padding: the fill, weight 0).
        self.band_maps: list[tuple[NDArray[np.float32], NDArray[np.float32]]] = []
        self.band_weights = np.zeros((self.count, band_rows, buffer_width), dtype=np.float32)
        for k, (map_uv, source) in enumerate(zip(maps, reads, strict=True)):
            (x, y), (w, h) = places[source], self.sources[source]
            self.masks.append(self._sole(k, map_uv, owners, (x, y), (w, h)))
            u, v = map_uv.reshape(-1, 2)[band].T
            with np.errstate(invalid="ignore"):
                valid = inside_image(u, v, (w, h))
            laid = []
            for entries, low, high, at in ((u, x, w, self._fill_at[0]), (v, y, h, self._fill_at[1])):
                row = np.full(band_rows * buffer_width, at, dtype=np.float32)
                row[: band.size] = np.where(valid, np.clip(entries, 0, high - 1) + np.float32(low), np.float32(at))
                laid.append(row.reshape(band_rows, buffer_width))
            self.band_maps.append((laid[0], laid[1]))
            self.band_weights[k].reshape(-1)[: band.size] = seams.band_weights[k]
        slot = np.arange(band.size)
        self.map_u.reshape(-1)[band] = slot % buffer_width
        self.map_v.reshape(-1)[band] = pictures_height + slot // buffer_width
        self._buffers(fill)

    def _sole(
        self,
        k: int,
        map_uv: NDArray[np.float32],
        owners: NDArray[np.uint8],
        place: tuple[int, int],
        size: tuple[int, int],
    ) -> tuple[tuple[slice, slice], NDArray[np.uint8]] | None:
        """Write camera ``k``'s entries where it takes the pixel alone (and is on its source) into the combined
        map, clamped to its source and moved to its place in the buffer; the mask of those pixels in its bounding
        box (None where there are none)."""
        (x, y), (w, h) = place, size
        alone = (owners == k).view(np.uint8)
        cv2.bitwise_and(alone, cv2.inRange(map_uv, (-0.5, -0.5), (w - 0.5, h - 0.5)), dst=alone)  # (inside_image)
        left, top, across, down = cv2.boundingRect(alone)
        if across == 0:
            return None
        box = (slice(top, top + down), slice(left, left + across))
        mask = np.ascontiguousarray(alone[box])
        entries = np.empty(mask.shape, dtype=np.float32)  # (one channel at a time: cv2.split took 3 x longer)
        for axis, low, high, target in ((0, x, w, self.map_u), (1, y, h, self.map_v)):
            np.clip(map_uv[box][..., axis], 0, high - 1, out=entries)
            if low:
                entries += np.float32(low)
            cv2.copyTo(entries, mask, target[box])
        return box, mask

    def _buffers(self, fill: float) -> None:
        """This plane's own buffer (its fill pixel set), band values and gains."""
        self.fill = float(fill)
        self.buffer = np.zeros(self._buffer_shape, dtype=np.uint8)
        self._fill_pixel(self._fill_at)
        self._band_out = self.buffer[self.band_top :].reshape(-1, *self.buffer.shape[2:])[: self.band_size]
        self._band_values = [np.empty(self.band_maps[0][0].shape + self.buffer.shape[2:], np.uint8)
                             for _ in range(self.count)]  # fmt: skip
        self.gains = np.ones((self.count, self.channels))
        self._scales: NDArray[np.float32] = self._scaled(self.gains)
        self._luts: list[NDArray[np.uint8] | None] = [None] * self.count

    def twin(self, fill: float) -> RigPlane:
        """A plane of the same maps and weights (shared, read only) with its own buffer and ``fill``: a video's
        second chroma plane."""
        other = copy.copy(self)
        other._buffers(fill)
        return other

    def _fill_pixel(self, at: tuple[int, int]) -> None:
        x, y = at
        self.buffer[y, x] = self.fill

    def _scaled(self, gains: NDArray[np.float64]) -> NDArray[np.float32]:
        """(k, rows, width[, C]) float32: each camera's band weights times its gains, as RigRemapper multiplies."""
        gain = gains.astype(np.float32)
        if self.channels == 1:
            return self.band_weights * gain[:, :1, None]
        return self.band_weights[..., None] * gain[:, None, None, :]

    def set_gains(self, gains: NDArray[np.float64]) -> None:
        """Each camera's gains ((k, C), or (k, 1) for every channel) from now on."""
        gains = np.broadcast_to(np.asarray(gains, dtype=np.float64), (self.count, self.channels)).copy()
        self.gains = gains
        self._scales = self._scaled(gains)
        levels = np.arange(256, dtype=np.float32)
        luts: list[NDArray[np.uint8] | None] = []
        for gain in gains.astype(np.float32):
            columns = [np.clip(np.rint(self.black + (levels - self.black) * g), 0, 255) for g in gain]
            lut = np.stack(columns, axis=-1).astype(np.uint8)
            identity = all(np.array_equal(column, levels) for column in columns)
            luts.append(None if identity else (lut[:, 0] if self.channels == 1 else lut.reshape(1, 256, -1)))
        self._luts = luts

    def load(self, pictures: Sequence[NDArray[Any]]) -> None:
        """Copy the pictures into the buffer (each checked against its size)."""
        if len(pictures) != len(self.sources):
            raise PanomapError(f"{len(pictures)} pictures for a plane of {len(self.sources)}")
        for picture, (x, y), (w, h) in zip(pictures, self.places, self.sources, strict=True):
            if picture.shape[:2] != (h, w) or picture.dtype != np.uint8:
                raise PanomapError(f"a picture is {picture.shape[1]} x {picture.shape[0]} {picture.dtype}, not "
                                   f"{w} x {h} uint8")  # fmt: skip
            self.buffer[y : y + h, x : x + w] = picture.reshape(self.buffer[y : y + h, x : x + w].shape)

    def band_layers(self) -> list[NDArray[np.uint8]]:
        """Each camera's band pixels (rows, width[, C]) from the loaded pictures (the fill where it does not see)."""
        for k, (map_u, map_v) in enumerate(self.band_maps):
            cv2.remap(self.buffer, map_u, map_v, self.interpolation, dst=self._band_values[k],
                      borderMode=cv2.BORDER_REPLICATE)  # fmt: skip
        return self._band_values

    def band_gains(self) -> NDArray[np.float64]:
        """(k, C) gains matching the cameras over the band of the loaded pictures (:func:`.blend.overlap_gains`)."""
        layers = []
        for values in self.band_layers():
            layer = values.reshape(1, -1, self.channels)[:, : self.band_size].astype(np.float32)
            layers.append(layer - np.float32(self.black) if self.black else layer)
        weights = self.band_weights.reshape(self.count, 1, -1)[:, :, : self.band_size]
        return overlap_gains(layers, weights, self.shares)

    def __call__(self, out: NDArray[np.uint8] | None = None) -> NDArray[np.uint8]:
        """The blended view of the loaded pictures (into ``out``: an array of :attr:`output_shape`, any strides)."""
        values = self.band_layers()
        if self.band_size:
            # (RigRemapper's sum, from zero, in the rig's order: 0 + x is x, so the first term is written)
            total = np.empty(values[0].shape, dtype=np.float32)
            term = np.empty_like(total)
            black = np.float32(self.black)
            for k, (layer, scale) in enumerate(zip(values, self._scales, strict=True)):
                into = total if k == 0 else term
                if self.black:
                    np.subtract(layer, black, out=into, dtype=np.float32)
                    np.multiply(into, scale, out=into)
                else:
                    np.multiply(layer, scale, out=into, dtype=np.float32)
                if k:
                    total += term
            if self.black:
                total += black
            band = total.reshape(-1, *self.buffer.shape[2:])[: self.band_size]
            np.clip(np.rint(band, out=band), 0, 255, out=band)
            if not self.band_is_all:
                self._band_out[...] = band
        if out is None:
            out = np.empty(self.output_shape, dtype=np.uint8)
        target = out if out.ndim == self.buffer.ndim else out.reshape(self.output_shape)
        if self.band_is_all:  # (every pixel blended: the band is the output, in order)
            target[...] = band.reshape(target.shape)
            return out
        written = cv2.remap(self.buffer, self.map_u, self.map_v, self.interpolation, dst=target,
                            borderMode=cv2.BORDER_REPLICATE)  # fmt: skip
        if not np.shares_memory(written, target):  # (never seen; a guard against a binding that copies)
            target[...] = written.reshape(target.shape)
        for lut, box in zip(self._luts, self.masks, strict=True):
            if lut is None or box is None:
                continue
            (rows, cols), mask = box
            part = target[rows, cols]
            cv2.copyTo(cv2.LUT(part, lut), mask, part)
        return out


def _layout(sizes: Sequence[tuple[int, int]]) -> tuple[list[tuple[int, int]], int, int]:
    """Where each picture of ``sizes`` (w, h) sits in the buffer (x, y): left to right in rows at most
    :data:`BUFFER_WIDTH` wide (wider pictures alone); the buffer's width and its pictures' height."""
    places, x, y, row_height, width = [], 0, 0, 0, 0
    for w, h in sizes:
        if x and x + w > BUFFER_WIDTH:
            x, y, row_height = 0, y + row_height, 0
        places.append((x, y))
        x += w
        width, row_height = max(width, x), max(row_height, h)
    return places, max(width, 1), y + row_height


class FastRigRemapper:
    """:class:`RigRemapper`'s view, blended the fast way (:class:`RigPlane`), for uint8 pictures of C channels.

    Parameters
    ----------
    remapper : RigRemapper
        The view (its rig, maps, weights, interpolation and fill).
    channels : int
        The pictures' channels (1, 3 or 4).
    """

    def __init__(self, remapper: RigRemapper, channels: int = 3) -> None:
        rig = remapper.rig
        self.rig = rig
        if rig.offsets is not None:
            frame = rig.frame_size
            assert frame is not None
            maps = [
                m + np.array(offset, dtype=np.float32) for m, offset in zip(remapper.maps, rig.offsets, strict=True)
            ]
            sources, reads = [frame], [0] * rig.count
        else:
            maps = list(remapper.maps)
            sources = [table.image_size for table in rig.tables]  # type: ignore[misc]
            reads = list(range(rig.count))
        self.plane = RigPlane(maps, remapper.seams, sources, reads, channels, remapper.interpolation,
                              remapper.fill)  # fmt: skip
        self.channels = channels

    def _load(self, pictures: Any) -> None:
        pictures = [pictures] if isinstance(pictures, np.ndarray) else list(pictures)
        if len(pictures) != len(self.plane.sources):
            wanted = "one frame holding them all" if self.rig.offsets is not None else f"{self.rig.count}"
            raise PanomapError(f"{len(pictures)} pictures for a rig of {self.rig.count} cameras: give {wanted}")
        self.plane.load(pictures)

    def gains(self, pictures: Any) -> NDArray[np.float64]:
        """(k, C) gains matching the cameras over their overlaps in ``pictures``."""
        self._load(pictures)
        return self.plane.band_gains()

    def __call__(self, pictures: Any, gains: NDArray[np.float64] | None = None) -> NDArray[np.uint8]:
        """The blended view of ``pictures`` (one frame, or one per camera), each camera scaled by ``gains``
        (default: found in these pictures)."""
        self._load(pictures)
        self.plane.set_gains(self.plane.band_gains() if gains is None else gains)
        return self.plane()
