"""The seams of a rig's view: the camera that takes each output pixel alone, and the feathered weights where
several share it.

Convention: maps as :mod:`panomap.remap` ((H, W, 2) float32 source (u, v), NaN where there is no source); flat
indices row-major over the view's (H, W); weights as :func:`.blend.feather_weights` states them (each camera's
distance in output px from the edge of what it sees, less the largest there plus ``2 f``, at least 0, over their
sum).

Most of a view is seen by one camera, or weighed by one alone (away from a seam the camera seeing a pixel
deepest takes it): its weight is exactly 1 (``w / w``). :class:`SeamWeights` keeps the weights that way: each
pixel's *owner* (the camera weighing 1; :data:`NONE` where none sees; :data:`BLENDED` where several weigh), and
the few blended pixels (the *band*) with every camera's weight. :func:`seam_weights` builds it with OpenCV's
masks and distance transforms and does the formula's float32 arithmetic on the cameras' overlap alone, the same
operations in the same order as over the whole view: :meth:`SeamWeights.dense` is, bit for bit, the weights
computed over every pixel (``tests/test_rig_video.py`` checks it against that formula written out). A video's
large views (:func:`video_seam_step`) take the distances from every 2nd row and column (:func:`coarse_distances`):
a quarter of the transform, the weights within 0.016 of those.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

# An owner's value where no camera sees the pixel (every weight 0), and where several weigh (the band).
NONE = -1
BLENDED = -2
# float32's largest finite value: cv2.inRange within +-it is "finite".
_FINITE = float(np.finfo(np.float32).max)
# Rows of this many pixels lay a list of pixels out for cv2.remap (its maps are below 32767 a side).
BUFFER_WIDTH = 16384
# The feather (output px) from which a video's distances are taken on a 2 x 2 grid (:func:`video_seam_step`).
COARSE_FEATHER_PX = 40.0


@dataclass(frozen=True)
class SeamWeights:
    """Every camera's weight at every pixel of a view, kept as owners and a band (module docstring).

    Parameters
    ----------
    owner : (H, W) int8
        The camera that weighs 1 there (the others 0); :data:`NONE`: no camera sees it (every weight 0);
        :data:`BLENDED`: two or more weigh, their weights in ``band_weights``.
    band : (n,) intp
        The flat indices of the :data:`BLENDED` pixels, ascending.
    band_weights : (k, n) float32
        Each camera's weight at them (summing to 1).
    """

    owner: NDArray[np.int8]
    band: NDArray[np.intp]
    band_weights: NDArray[np.float32]

    @property
    def count(self) -> int:
        """How many cameras."""
        return int(self.band_weights.shape[0])

    @property
    def shape(self) -> tuple[int, int]:
        """(H, W) of the view."""
        return int(self.owner.shape[0]), int(self.owner.shape[1])

    def shares(self) -> NDArray[np.float64]:
        """(k,) float64: each camera's share of the view, its weights' sum over every pixel (px)."""
        counts = np.bincount(self.owner[self.owner >= 0].astype(np.intp), minlength=self.count)[: self.count]
        return counts.astype(np.float64) + self.band_weights.sum(axis=1, dtype=np.float64)

    def dense(self) -> NDArray[np.float32]:
        """(k, H, W) float32: every camera's weight at every pixel."""
        out = np.zeros((self.count, *self.shape), dtype=np.float32)
        for k in range(self.count):
            np.copyto(out[k], self.owner == k)
        out.reshape(self.count, -1)[:, self.band] = self.band_weights
        return out

    def at(self, flat: NDArray[np.intp]) -> NDArray[np.float32]:
        """(k, m) float32: every camera's weight at the pixels of flat indices ``flat`` (m,)."""
        owner = self.owner.reshape(-1)[flat]
        weights = (owner[None, :] == np.arange(self.count, dtype=np.int8)[:, None]).astype(np.float32)
        blended = np.flatnonzero(owner == BLENDED)
        if blended.size:
            weights[:, blended] = self.band_weights[:, np.searchsorted(self.band, flat[blended])]
        return weights

    def subsampled(self, maps: Sequence[NDArray[np.float32]], sub_x: int, sub_y: int) -> SeamWeights:
        """The weights of a plane subsampled by ``2**sub_x`` across and ``2**sub_y`` down (a chroma plane), its
        cameras' maps ``maps`` ((ceil(H/sy), ceil(W/sx), 2), NaN where a camera has no entry): each block's sum
        of these weights (the view's edge repeated where the size is odd), 0 where the camera's map has no
        entry, over their sum. A block one camera owns whole is that camera's (weight ``s / s``: 1); the others
        are computed."""
        sx, sy = 1 << sub_x, 1 << sub_y
        height, width = self.shape
        owner = self.owner
        if height % sy or width % sx:
            owner = np.pad(owner, ((0, -height % sy), (0, -width % sx)), mode="edge")
        first = owner[0::sy, 0::sx]
        uniform = np.ones(first.shape, dtype=bool)
        for dy in range(sy):
            for dx in range(sx):
                if dy or dx:
                    uniform &= owner[dy::sy, dx::sx] == first
        sub_owner = np.where(uniform, first, np.int8(BLENDED))
        candidates = np.flatnonzero(sub_owner == BLENDED)
        rows, cols = np.divmod(candidates, sub_owner.shape[1])
        # (the blocks' sums from zero in the order (0, 0), (0, 1), (1, 0), (1, 1): 0 + w is w)
        sums = np.zeros((self.count, candidates.size), dtype=np.float32)
        for dy in range(sy):
            for dx in range(sx):
                flat = np.minimum(rows * sy + dy, height - 1) * width + np.minimum(cols * sx + dx, width - 1)
                sums += self.at(flat)
        for k, map_uv in enumerate(maps):
            entries = map_uv.reshape(-1, 2)[candidates]
            sums[k][~np.all(np.isfinite(entries), axis=-1)] = 0
        total = sums.sum(axis=0)
        np.divide(sums, total, out=sums, where=total > 0)
        return _settled(sub_owner, candidates, sums)


def seam_weights(
    maps: Sequence[NDArray[np.float32]], wrap: bool = False, feather_px: float | None = None, step: int = 1
) -> SeamWeights:
    """The feathered weights of the cameras whose maps are ``maps`` (each (H, W, 2), NaN where it does not see),
    as :func:`.blend.feather_weights` defines them. ``wrap``: the columns wrap around (a panorama: the
    distances wrap too). ``feather_px``: the feather ``f`` (output px; default :func:`default_feather_px`;
    ``inf``: the distances alone, across the whole overlap). ``step``: the distances' grid (output px): 1, every
    pixel's; ``s`` > 1, the distance transform of every ``s``-th row and column of what each camera sees,
    interpolated (:func:`coarse_distances`; :func:`video_seam_step` says where that is within bounds)."""
    count = len(maps)
    height, width = maps[0].shape[:2]
    feather = default_feather_px((height, width)) if feather_px is None else float(feather_px)
    seen = [np.asarray(cv2.inRange(map_uv, (-_FINITE, -_FINITE), (_FINITE, _FINITE)), dtype=np.uint8)
            for map_uv in maps]  # fmt: skip  # (255: it sees)
    seers = np.zeros((height, width), dtype=np.uint8)
    ids = np.zeros((height, width), dtype=np.uint8)
    for k, mask in enumerate(seen):
        bit = mask >> 7
        seers += bit
        if k:
            ids += bit * np.uint8(k)
    # Where one camera sees, it weighs d - (d - 2f) > 0 over itself: 1 (0 with a feather of 0 or less).
    alone_weighs = not np.isfinite(feather) or 2 * feather > 0
    if alone_weighs:
        ids |= (seers == 0).view(np.uint8) * np.uint8(255)  # (ids is 0 there: 255, NONE as int8)
    else:
        ids[...] = 255
    owner = ids.view(np.int8)
    overlap = np.flatnonzero(seers >= 2)
    if overlap.size == 0:
        return SeamWeights(owner, overlap, np.zeros((count, 0), dtype=np.float32))
    pad = width // 4 if wrap else 0
    # (the overlap's flat indices in the padded picture: one np.take each, 4 x faster than indexing rows, cols)
    padded_at = overlap + (overlap // width) * (2 * pad) + pad if pad else overlap
    distances = np.zeros((count, overlap.size), dtype=np.float32)
    sees = np.zeros((count, overlap.size), dtype=bool)

    def distance(k: int) -> None:
        mask = seen[k]
        sees[k] = mask.reshape(-1)[overlap] != 0
        if not sees[k].any():  # (its distance is 0 wherever it does not see)
            return
        if step > 1:
            distances[k] = coarse_distances(mask, overlap, step, wrap)
            return
        padded = cv2.copyMakeBorder(mask, 0, 0, pad, pad, cv2.BORDER_WRAP) if pad else mask
        np.take(cv2.distanceTransform(padded, cv2.DIST_L2, cv2.DIST_MASK_PRECISE).reshape(-1), padded_at,
                out=distances[k])  # fmt: skip

    # The cameras' distance transforms side by side (OpenCV lets go of the GIL; each its own, as one after another).
    with ThreadPoolExecutor(min(count, os.cpu_count() or 1), thread_name_prefix="panomap-seams") as pool:
        list(pool.map(distance, range(count)))
    weights = distances
    if np.isfinite(feather):
        weights -= weights.max(axis=0) - np.float32(2 * feather)
        np.maximum(weights, 0, out=weights)
        np.multiply(weights, sees, out=weights)  # (0 where the camera does not see: w x 1 is w; w >= 0)
    total = weights.sum(axis=0)
    np.divide(weights, total, out=weights, where=total > 0)
    return _settled(owner, overlap, weights)


def coarse_distances(mask: NDArray[np.uint8], flat: NDArray[np.intp], step: int, wrap: bool) -> NDArray[np.float32]:
    """(m,) float32: the distance (output px) from the pixels at flat indices ``flat`` (m,) of ``mask`` (H, W; 0
    where the camera does not see) to the nearest pixel where it does not see, from the exact distance transform
    of the mask's every ``step``-th row and column (the nodes: pixel ``(step i, step j)``), read bilinearly at
    ``(x / step, y / step)`` and scaled by ``step``. ``wrap``: the columns wrap around, as :func:`seam_weights`
    pads them (a quarter of the width each side).

    The distance to an edge is 1-Lipschitz, so the interpolation adds at most ``step / sqrt(2)`` px, and the
    nodes see the edge within ``step / sqrt(2)``: ``|d - d_full| <= sqrt(2) step`` px (measured on the 4K dual
    fisheye's equirect, step 2: at most 1.53 px, 99% within 1.31; ``tests/test_rig_video.py`` checks closed
    forms). A transform of ``1 / step**2`` of the pixels."""
    width = mask.shape[1]
    coarse: NDArray[np.uint8] = np.ascontiguousarray(mask[::step, ::step])
    pad = -(-(width // 4) // step) if wrap else 0
    if pad:  # (wrapping: the node after the last column is column 0's, in the padding)
        coarse = np.asarray(cv2.copyMakeBorder(coarse, 0, 0, pad, pad, cv2.BORDER_WRAP), dtype=np.uint8)
    field = cv2.distanceTransform(coarse, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    # Read at the pixels' node coordinates, laid out as rows for cv2.remap (bilinear; past the last node, not
    # wrapping: the last repeated); 1.25 M pixels a camera: 2 ms, where NumPy's four gathers took 75.
    across = min(flat.size, BUFFER_WIDTH)
    down = -(-flat.size // across)
    map_x = np.zeros(down * across, dtype=np.float32)
    map_y = np.zeros(down * across, dtype=np.float32)
    y, x = np.divmod(flat, mask.shape[1])
    np.multiply(x, np.float32(1 / step), out=map_x[: flat.size], casting="unsafe")
    np.multiply(y, np.float32(1 / step), out=map_y[: flat.size], casting="unsafe")
    if pad:
        map_x += np.float32(pad)
    read = cv2.remap(field, map_x.reshape(down, across), map_y.reshape(down, across), cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_REPLICATE)  # fmt: skip
    return np.multiply(read.reshape(-1)[: flat.size], np.float32(step), dtype=np.float32)


def video_seam_step(shape: tuple[int, int]) -> int:
    """The distances' grid (:func:`seam_weights` ``step``) for a video's view of ``shape`` (H, W): 2 where the
    feather is at least :data:`COARSE_FEATHER_PX`, else 1 (every pixel's). A weight moves at most ``1 / (2 f)``
    per px its cameras' distances move apart; on the 4K dual fisheye's equirect (``f`` 43 px) the 2 x 2 grid
    moved the weights by at most 0.016 and the blended luma by at most 1 grey level (one lens 15% brighter, the
    gains found or not), and took the weights' set-up from 0.25 to 0.12 s."""
    return 2 if default_feather_px(shape) >= COARSE_FEATHER_PX else 1


def _settled(owner: NDArray[np.int8], flat: NDArray[np.intp], weights: NDArray[np.float32]) -> SeamWeights:
    """``owner`` with the pixels at ``flat`` settled by their weights ``weights`` (k, m): one camera weighing
    there owns it, none: :data:`NONE`, several: :data:`BLENDED` (the band, with their weights)."""
    weighing = np.count_nonzero(weights > 0, axis=0)
    several = weighing >= 2
    # (np.argmax over the cameras, as a running maximum: its first camera of the largest weight, 10 x faster)
    heaviest = np.zeros(weights.shape[1], dtype=np.int8)
    largest = weights[0] if len(weights) else np.zeros(0, dtype=weights.dtype)
    for k in range(1, len(weights)):
        np.copyto(heaviest, np.int8(k), where=weights[k] > largest)
        largest = np.maximum(largest, weights[k])
    settled = np.where(weighing == 1, heaviest, np.int8(NONE))
    settled[several] = BLENDED
    owner.reshape(-1)[flat] = settled
    return SeamWeights(owner, flat[several], np.ascontiguousarray(weights[:, several]))


def default_feather_px(shape: tuple[int, ...]) -> float:
    """The feather (output px) of a view of ``shape`` (H, W): 1% of its diagonal, at least 8 px."""
    return max(8.0, 0.01 * float(np.hypot(shape[0], shape[1])))
