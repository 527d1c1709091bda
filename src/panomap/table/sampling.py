"""Sampling a pano-mapping table at any rays: the table's entries as images for ``cv2.remap``.

Convention: entry (i, j) of an (M, N) table is the pixel of azimuth
``theta_i = 2*pi*i/M`` and elevation ``rho_j = rho_s + j*(rho_e - rho_s)/N``;
a ray is read at the fractional indices ``fi = theta*M/(2*pi)``,
``fj = (rho - rho_s)*N/(rho_e - rho_s)``.

- ``bilinear`` (default): linear in both, wrapping in azimuth. The table has no
  entry at rho_e itself, so the last cell [rho_{N-1}, rho_e] continues the
  line through the last two entries.
- ``nearest``: floor indices, exactly the paper's eqs. (9), (12), (19), (22).

Rays outside [rho_s, rho_e], or landing outside the image, get NaN.

The sampling itself is ``cv2.remap`` over the entries laid out as two float32
images (u and v), padded with the azimuth wrap and the extrapolated last cell.
OpenCV 5 interpolates 1-, 3- and 4-channel float32 images with exact float
weights (older versions, and 2-channel images, use 1/32 steps), so the result
is the bilinear interpolation of the entries in float32 arithmetic: within
1.5e-4 px of a float64 evaluation for coordinates below 1024 px, 3e-4 px below
2048 px (about two float32 steps). Indices are computed in the angles'
precision (float32 angles give float32 indices).
"""

from __future__ import annotations

import math
from functools import cache
from typing import Any, NamedTuple

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import PanomapError
from ..geometry import TWO_PI, inside_image
from ..strips import in_strips

SAMPLINGS = ("bilinear", "nearest")
# cv2.remap takes images and maps below 32767 px a side; the padded table must fit.
MAX_TABLE_SIDE = 32_000
# A row index that reads only the NaN border of the sampling images (invalid pixels go there).
OUTSIDE = -4.0
# A grid's map is read this many pixels at a time (:func:`sample_grid`).
GRID_BLOCK_PX = 1 << 18
# float32 NaN's bits, as an int32.
_NAN_BITS = int(np.array(np.nan, dtype=np.float32).view(np.int32))


class RemapImages(NamedTuple):
    """An (M, N) table's entries as (N + 2, M + 3) float32 u and v images for ``cv2.remap``.

    ``all_inside`` says whether every value lies inside the image (then the
    bounds check can be skipped).
    """

    u: NDArray[np.float32]
    v: NDArray[np.float32]
    all_inside: bool


def check_sampling(sampling: object) -> str:
    """``sampling`` if it is one of :data:`SAMPLINGS` (how a table is read between its entries); PanomapError
    otherwise."""
    if not isinstance(sampling, str) or sampling not in SAMPLINGS:
        raise PanomapError(f"table sampling must be bilinear or nearest, not {sampling!r:.40}")
    return sampling


def remap_images(entries: NDArray[np.float32], image_size: tuple[int, int] | None) -> RemapImages:
    """The entries (M, N, 2) as images for ``cv2.remap``, read-only.

    Row j, column i holds entry (i, j): azimuth runs along the rows, as it
    does along most views' rows, which keeps reads close together. Columns
    M..M+2 repeat columns 0..2 (the azimuth wrap); row N continues the
    line through the last two entries (the last cell reaches rho_e) and
    row N+1 repeats it, so every read of a valid index is finite.
    """
    _check_exact_remap()
    m, n = entries.shape[:2]
    u_image = np.empty((n + 2, m + 3), dtype=np.float32)
    v_image = np.empty((n + 2, m + 3), dtype=np.float32)
    transposed = cv2.transpose(np.ascontiguousarray(entries))  # (N, M, 2), cache-blocked
    for channel, image in enumerate((u_image, v_image)):
        image[:n, :m] = transposed[..., channel]
        image[:n, m:] = image[:n, np.arange(3) % m]
        # 2a - b of float32 values is exact in float64, so float32 arithmetic rounds it the same way.
        image[n] = 2 * image[n - 1] - image[n - 2]
        image[n + 1] = image[n]
    all_inside = True
    if image_size is not None:
        # The padded images' bounding box: inside when its two corners are.
        all_inside = bool(
            inside_image(u_image.min(), v_image.min(), image_size)
            and inside_image(u_image.max(), v_image.max(), image_size)
        )
    for image in (u_image, v_image):
        image.setflags(write=False)
    return RemapImages(u_image, v_image, all_inside)


def sample_entries(
    images: RemapImages,
    elevation_range: tuple[float, float],
    image_size: tuple[int, int] | None,
    theta: ArrayLike,
    rho: ArrayLike,
    sampling: str = "bilinear",
    *,
    overwrite: bool = False,
) -> NDArray[np.float32]:
    """Pixels (..., 2) of rays read from a table's :func:`remap_images`.

    See :meth:`panomap.table.table.PanoMappingTable.sample`, which this is.
    """
    check_sampling(sampling)
    theta_in, rho_in = np.broadcast_arrays(np.asarray(theta), np.asarray(rho))
    dtype = np.float32 if theta_in.dtype == np.float32 and rho_in.dtype == np.float32 else np.float64
    shape = theta_in.shape
    count = theta_in.size
    if count == 0:
        return np.empty((*shape, 2), dtype=np.float32)
    n, m = images.u.shape[0] - 2, images.u.shape[1] - 3
    rho_s, rho_e = elevation_range
    rows, cols = _remap_grid(shape)
    reuse = (
        overwrite
        and dtype == np.float32
        and (rows, cols) == shape
        and all(isinstance(a, np.ndarray) and a.flags.c_contiguous and a.flags.writeable for a in (theta, rho))
        and not np.may_share_memory(theta, rho)
    )
    fi_flat: NDArray[np.floating[Any]]
    fj_flat: NDArray[np.floating[Any]]
    if reuse:
        fi_flat, fj_flat = np.asarray(theta).reshape(-1), np.asarray(rho).reshape(-1)
    else:
        fi_flat, fj_flat = np.empty(rows * cols, dtype), np.empty(rows * cols, dtype)
    fi = fi_flat[:count].reshape(shape)
    fj = fj_flat[:count].reshape(shape)
    np.multiply(theta_in, m / TWO_PI, out=fi, casting="unsafe")
    np.subtract(rho_in, rho_s, out=fj, casting="unsafe")
    fj *= n / (rho_e - rho_s)
    fi_flat[count:] = 0.0
    fj_flat[count:] = OUTSIDE
    interpolation = _to_table_indices(fi_flat, fj_flat, m, n, sampling)
    map_x = fi_flat.astype(np.float32, copy=False).reshape(rows, cols)
    map_y = fj_flat.astype(np.float32, copy=False).reshape(rows, cols)
    uv = _read(images, image_size, map_x, map_y, interpolation)
    return np.asarray(uv.reshape(-1, 2)[:count].reshape(*shape, 2), dtype=np.float32)


def sample_grid(
    images: RemapImages,
    elevation_range: tuple[float, float],
    image_size: tuple[int, int] | None,
    theta: ArrayLike,
    rho: ArrayLike,
    sampling: str = "bilinear",
) -> NDArray[np.float32]:
    """Pixels (H, W, 2) of the grid of rays ``theta[k]`` (W,) by ``rho[l]`` (H,), read from :func:`remap_images`.

    The same map as :func:`sample_entries` of the broadcast (H, W) angles,
    value for value where the angles are finite, from one row of indices and
    one column (a panorama's).
    """
    check_sampling(sampling)
    theta_in, rho_in = np.asarray(theta).reshape(-1), np.asarray(rho).reshape(-1)
    dtype = np.float32 if theta_in.dtype == np.float32 and rho_in.dtype == np.float32 else np.float64
    n, m = images.u.shape[0] - 2, images.u.shape[1] - 3
    rho_s, rho_e = elevation_range
    fi: NDArray[np.floating[Any]] = np.empty(theta_in.size, dtype)
    fj: NDArray[np.floating[Any]] = np.empty(rho_in.size, dtype)
    np.multiply(theta_in, m / TWO_PI, out=fi, casting="unsafe")
    np.subtract(rho_in, rho_s, out=fj, casting="unsafe")
    fj *= n / (rho_e - rho_s)
    with np.errstate(invalid="ignore"):
        if not (fi.size and bool(fi.min() >= 0) and bool(fi.max() <= m + 1)):
            fi -= m * np.floor(fi / m)
            # A column of NaN azimuths reads the border (NaN), as sample_entries sends it there.
            np.copyto(fi, OUTSIDE, where=~np.isfinite(fi))
        # Rows outside the range read only the NaN border (sample_entries gets NaN there too).
        np.copyto(fj, OUTSIDE, where=~((fj >= 0) & (fj <= n)))
    if sampling == "nearest":
        np.floor(fi, out=fi)
        np.floor(fj, out=fj)
        np.minimum(fj, n - 1, out=fj)
    interpolation = cv2.INTER_NEAREST if sampling == "nearest" else cv2.INTER_LINEAR
    width, height = fi.size, fj.size
    columns, rows = fi.astype(np.float32), fj.astype(np.float32)
    out = np.empty((height, width, 2), dtype=np.float32)

    def strip(start: int, stop: int) -> None:
        # A few rows at a time through the same small read positions: a 3840 x 1920 map's strips took 4 x 15 MB
        # of new memory each (the positions and OpenCV's u and v), 30,000 page faults a camera, where these reuse
        # 1 MB.
        block = max(1, min(stop - start, GRID_BLOCK_PX // max(width, 1)))
        map_x = np.empty((block, width), dtype=np.float32)
        map_y = np.empty_like(map_x)
        map_x[...] = columns
        for top in range(start, stop, block):
            count = min(block, stop - top)
            map_y[:count] = rows[top : top + count, None]
            _read(images, image_size, map_x[:count], map_y[:count], interpolation, out=out[top : top + count])

    in_strips(height, strip)
    return out


def _to_table_indices(fi_flat: NDArray[Any], fj_flat: NDArray[Any], m: int, n: int, sampling: str) -> int:
    """Turn fractional indices into the images' read positions, in place; return the cv2 interpolation.

    Invalid rays are sent to the NaN border; nearest sampling floors.
    """
    with np.errstate(invalid="ignore"):
        # The padded images hold columns M..M+2 (= 0..2): indices up to M + 1 need no wrapping.
        # NaN anywhere makes these comparisons false, and the careful path below runs.
        plain = bool(fi_flat.min() >= 0) and bool(fi_flat.max() <= m + 1)
        highest = fj_flat.max()
        plain &= bool(np.isfinite(fj_flat.min())) and bool(np.isfinite(highest))
        if plain:
            # Below rho_s the reads reach the NaN border by themselves; beyond rho_e they must be sent there.
            if highest > n:
                np.copyto(fj_flat, OUTSIDE, where=fj_flat > n)
        else:
            fi_flat -= m * np.floor(fi_flat / m)
            invalid = ~((fj_flat >= 0) & (fj_flat <= n) & np.isfinite(fi_flat))
            np.copyto(fi_flat, 0.0, where=invalid)
            np.copyto(fj_flat, OUTSIDE, where=invalid)
    if sampling == "nearest":
        np.floor(fi_flat, out=fi_flat)
        np.floor(fj_flat, out=fj_flat)
        np.minimum(fj_flat, n - 1, out=fj_flat)
        return cv2.INTER_NEAREST
    return cv2.INTER_LINEAR


def _read(
    images: RemapImages,
    image_size: tuple[int, int] | None,
    map_x: NDArray[np.float32],
    map_y: NDArray[np.float32],
    interpolation: int,
    out: NDArray[np.float32] | None = None,
) -> NDArray[np.float32]:
    """The (rows, cols, 2) pixels at read positions ``map_x``, ``map_y``; NaN off the image.

    Written into ``out`` (C-contiguous, float32) when given.
    """
    u_image, v_image, all_inside = images
    u = cv2.remap(u_image, map_x, map_y, interpolation, borderMode=cv2.BORDER_CONSTANT, borderValue=math.nan)
    v = cv2.remap(v_image, map_x, map_y, interpolation, borderMode=cv2.BORDER_CONSTANT, borderValue=math.nan)
    uv = cv2.merge([u, v]) if out is None else cv2.merge([u, v], dst=out)
    if not all_inside and image_size is not None:
        width, height = image_size
        outside = cv2.inRange(uv, (-0.5, -0.5), (width - 0.5, height - 0.5))  # (inside_image, in OpenCV)
        cv2.bitwise_not(outside, dst=outside)
        # NaN there: its bits (0x7FC00000) set in the float32s' bits, in OpenCV (NumPy's masked writes are slow)
        bits = uv.view(np.int32)
        none: Any = (0, 0, 0, 0)  # (a scalar, which OpenCV takes as a tuple; its stubs want an array)
        nan: Any = (_NAN_BITS, _NAN_BITS, 0, 0)
        cv2.bitwise_and(bits, none, dst=bits, mask=outside)
        cv2.bitwise_or(bits, nan, dst=bits, mask=outside)
    return np.asarray(uv, dtype=np.float32)


def _remap_grid(shape: tuple[int, ...]) -> tuple[int, int]:
    """(rows, cols) to lay ``shape``'s elements out for ``cv2.remap`` (below 32767 a side)."""
    if len(shape) == 2 and 0 < shape[0] < MAX_TABLE_SIDE and 0 < shape[1] < MAX_TABLE_SIDE:
        return shape[0], shape[1]
    count = math.prod(shape)
    cols = min(count, 16_384)
    return -(-count // cols), cols


@cache
def _check_exact_remap() -> None:
    """Refuse an OpenCV whose ``remap`` interpolates float32 images in 1/32 steps (before 5.0)."""
    image = np.array([[0.0, 1000.0], [0.0, 1000.0]], dtype=np.float32)
    at = np.full((1, 1), 0.3, dtype=np.float32)
    value = float(cv2.remap(image, at, np.zeros_like(at), cv2.INTER_LINEAR)[0, 0])
    if abs(value - 300.0) > 1e-3:
        raise PanomapError(
            f"OpenCV {cv2.__version__} interpolates float images in 1/32-pixel steps; panomap needs OpenCV >= 5.0"
        )
