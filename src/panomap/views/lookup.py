"""Maps with no per-pixel trigonometry: the table resampled once into a direction-indexed lookup.

The exact way to build a map (:func:`~panomap.views.base.build_map` with
``exact=True``) takes every pixel's azimuth and elevation (two ``arctan2``
over the whole view) and samples the table there. The perspective and floor
views instead read their rays here, in a handful of array passes and one
``cv2.remap`` per coordinate, from a lookup made once per table:

- **The lookup** is the table sampled (bilinear, as the exact path samples it)
  at the texels of an S x S image over the stereographic projection of ray
  directions from the pole the table does not see. A ray d (any length) lands
  at ``p = (d_x, d_y)/(|d| + c*d_z)``, with ``c = -1`` for a table looking down
  (``rho_s + rho_e < 0``: the projection is from straight up) and ``c = +1``
  for one looking up; texel (X, Y) holds ``p = ((X, Y) - c0)/K``. The
  visible pole is at the centre, azimuth is ``atan2(p_y, p_x)`` and the angle
  from the visible pole ``2*atan(|p|)``.
- **A map** is then ``(X, Y) = c0 + K*(d_x, d_y)/(|d| + c*d_z)`` read from the
  lookup by ``cv2.remap``: no transcendental function per pixel.
- **Accuracy.** Texels are ``LOOKUP_STEP`` rad apart at the visible pole and
  closer elsewhere, so interpolating the lookup reproduces the exact map to
  about 2e-3 px (``bench/bench_views.py`` prints the largest difference; the
  tests bound it on several cameras).
- **Validity** is decided exactly, not from the lookup: a ray has a source when
  its elevation is in [rho_s, rho_e], i.e. when ``q = d_z/(|d| + c*d_z)``
  (increasing with sin(rho)) is in the range of the ends, and (for tables whose
  entries leave the image) when the pixel lies on the image. The lookup extends
  the table's first and last cells linearly a few rows beyond its range, so the
  texels next to the edge of the range are as exact as the others.

A table whose far edge is too far past the horizon for the lookup to stay
small (``MAX_LOOKUP_SIDE``) gets no lookup; its views take the exact path.
"""

from __future__ import annotations

import math
import threading
import weakref
from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from ..geometry import TWO_PI, FloatArray, inside_image
from ..table.table import PanoMappingTable

# Texel spacing (rad) at the visible pole; it shrinks towards the far edge. The error is mostly
# float32 rounding: the worst measured is 0.002 px (a hyperbolic mirror, 800 px image) at 5e-3,
# 0.001 px at 2.5e-3; halving the step quadruples the memory (9 MB at 5e-3 for a table reaching
# 15 deg above the horizon), and a larger lookup reads more slowly (fewer cache hits).
LOOKUP_STEP = 5e-3
# Texels beyond the far edge of the range, so that pixels near it read only texels of the lookup.
EDGE_TEXELS = 3
# At most this many texels a side (two float32 images, 32 MB); tables reaching further past
# the horizon (about 47 deg) have no lookup.
MAX_LOOKUP_SIDE = 2048

# Rays whose elevations' sines are known to lie this far inside the table's are all valid unchecked
# (far more than float32 rounding).
SINE_MARGIN = 1e-4

# cv2.LUT of a validity mask (0 or 255): NaN where invalid, 0 where valid.
_NAN_UNLESS_VALID = np.full((1, 256), np.nan, dtype=np.float32)
_NAN_UNLESS_VALID[0, 255] = 0.0


@dataclass(frozen=True)
class DirectionLookup:
    """A table resampled over ray directions (see the module docstring).

    Attributes
    ----------
    u, v : (S, S) float32 ndarray
        The pixel of the ray through each texel (read-only); NaN far outside the table's range.
    pole : float
        c: -1 for a table looking down, +1 for one looking up.
    scale, centre : float
        K (texels per unit of p) and c0 (the texel of p = 0).
    q_range : (float, float)
        ``K*q`` of the table's first and last elevations.
    sine_range : (float, float)
        Their sines.
    image_size : (width, height) or None
        Where pixels must land to have a source; None when every entry is on the image.
    """

    u: NDArray[np.float32]
    v: NDArray[np.float32]
    pole: float
    scale: float
    centre: float
    q_range: tuple[float, float]
    sine_range: tuple[float, float]
    image_size: tuple[int, int] | None


_LOOKUPS: dict[int, DirectionLookup | None] = {}


_ASKED: set[int] = set()


def lookup_when_worth_it(table: PanoMappingTable) -> DirectionLookup | None:
    """The table's lookup from the second map of it on; None for the first (which then takes the exact way).

    Making the lookup costs about as much as two exact maps: a lone map (a still
    render, one view of a video) is made sooner the exact way; from a second map
    of the same table on (a PTZ view that moves, several views) the lookup pays.
    """
    key = id(table)
    if key in _LOOKUPS:
        return _LOOKUPS[key]
    if key not in _ASKED:
        _ASKED.add(key)
        weakref.finalize(table, _ASKED.discard, key)
        return None
    return direction_lookup(table)


def direction_lookup(table: PanoMappingTable) -> DirectionLookup | None:
    """The table's lookup, made on first use and kept while the table lives; None when it has none."""
    key = id(table)
    if key not in _LOOKUPS:
        _LOOKUPS[key] = make_lookup(table)
        weakref.finalize(table, _LOOKUPS.pop, key, None)
    return _LOOKUPS[key]


def make_lookup(table: PanoMappingTable, step: float = LOOKUP_STEP) -> DirectionLookup | None:
    """Sample ``table`` into a :class:`DirectionLookup` of texels ``step`` rad apart at the visible pole."""
    m, n = table.size
    rho_s, rho_e = table.elevation_range
    pole = -1.0 if rho_s + rho_e < 0 else 1.0
    # Angle of the table's far edge from the visible pole, and where it lands (|p|).
    far = math.pi / 2 + (rho_e if pole < 0 else -rho_s)
    scale = 2.0 / step  # dp/dangle is 1/2 at the pole
    half = math.ceil(scale * math.tan(far / 2) + EDGE_TEXELS) if far < math.pi - 1e-6 else MAX_LOOKUP_SIDE
    side = 2 * half + 1
    if side > MAX_LOOKUP_SIDE:
        return None
    centre = float(half)

    # The table's entries as images, row j + pad holding elevation row j, the first and last cells
    # continued linearly by pad rows (the exact path continues the last cell the same way), and
    # columns M..M+2 repeating 0..2 (the azimuth wrap).
    row_step = (rho_e - rho_s) / n
    pad = math.ceil(2 * step / row_step) + 2
    transposed = cv2.transpose(np.ascontiguousarray(table.entries))  # (N, M, 2)
    images = []
    for channel in (0, 1):
        image = np.empty((n + 2 * pad, m + 3), dtype=np.float32)
        image[pad : pad + n, :m] = transposed[..., channel]
        first, second, before, last = (transposed[j, :, channel].astype(np.float64) for j in (0, 1, n - 2, n - 1))
        for k in range(1, pad + 1):
            image[pad - k, :m] = first - k * (second - first)
            image[pad + n - 1 + k, :m] = last + k * (last - before)
        image[:, m:] = image[:, np.arange(3) % m]
        images.append(image)

    # Each texel's azimuth and elevation as table indices, in float64, for one quadrant (x, y >= 0,
    # the axes included); the others follow by symmetry about the centre.
    p = np.arange(half + 1) / scale
    theta = np.arctan2(p[:, None], p[None, :])
    rho = pole * (math.pi / 2 - 2 * np.arctan(np.hypot(p[:, None], p[None, :])))
    map_y = _unfold(((rho - rho_s) / row_step + pad).astype(np.float32), lambda quadrant: quadrant)
    to_index = m / TWO_PI
    map_x = _unfold(
        (theta * to_index).astype(np.float32),
        lambda quadrant: np.float32(m / 2) - quadrant,  # pi - theta, to the left of the axis
        lambda quadrant: np.float32(m / 2) + quadrant,  # pi + theta, below and left
        lambda quadrant: np.float32(m) - quadrant,  # 2 pi - theta, below and right
    )
    u, v = (_remap(image, map_x, map_y) for image in images)
    for image in (u, v):
        image.setflags(write=False)

    def k_q(rho: float) -> float:
        sine = math.sin(rho)
        return scale * sine / (1 + pole * sine) if 1 + pole * sine > 0 else -pole * math.inf

    # As the exact path decides it: every value it can read, the extrapolated last row included.
    reach = [image[pad : pad + n + 1] for image in images]
    all_inside = table.image_size is None or bool(
        inside_image(reach[0].min(), reach[1].min(), table.image_size)
        and inside_image(reach[0].max(), reach[1].max(), table.image_size)
    )
    return DirectionLookup(
        u,
        v,
        pole,
        scale,
        centre,
        (k_q(rho_s), k_q(rho_e)),
        (math.sin(rho_s), math.sin(rho_e)),
        None if all_inside else table.image_size,
    )


def _unfold(
    quadrant: NDArray[np.float32],
    left: Callable[[NDArray[np.float32]], NDArray[np.float32]],
    below_left: Callable[[NDArray[np.float32]], NDArray[np.float32]] | None = None,
    below: Callable[[NDArray[np.float32]], NDArray[np.float32]] | None = None,
) -> NDArray[np.float32]:
    """The (2h + 1) square image whose quadrant x, y >= 0 is ``quadrant`` ((h + 1) square, row y, column x).

    The other quadrants are the mirror images of ``quadrant`` passed through ``left`` (x < 0),
    ``below_left`` and ``below`` (y < 0); the last two default to ``left`` and the identity.
    """
    below_left = left if below_left is None else below_left
    below = below if below is not None else (lambda values: values)
    h = quadrant.shape[0] - 1
    out = np.empty((2 * h + 1, 2 * h + 1), dtype=np.float32)
    out[h:, h:] = quadrant
    out[h:, :h] = left(quadrant[:, :0:-1])
    out[:h, h:] = below(quadrant[:0:-1, :])
    out[:h, :h] = below_left(quadrant[:0:-1, :0:-1])
    return out


def lookup_map(
    lookup: DirectionLookup,
    rows: list[FloatArray],
    cols: list[FloatArray],
    length: NDArray[np.float32],
    sine_range: tuple[float, float] | None = None,
) -> NDArray[np.float32]:
    """The (H, W, 2) float32 map of rays ``d[l, k, a] = rows[a][l] + cols[a][k]`` (world axes), NaN without a source.

    Parameters
    ----------
    lookup : DirectionLookup
    rows : three (H,) arrays
    cols : three (W,) arrays
        The rays' x, y and z components as a row term plus a column term (as
        :func:`~panomap.views.grid.grid_angles` takes them).
    length : (H, W) float32 ndarray
        ``|d|`` of every ray.
    sine_range : (float, float), optional
        Bounds of ``d_z/|d|`` over the rays, when the view knows them: rays
        well inside the table's range need no check of their elevation.
    """
    return read_lookup(lookup, *lookup_coordinates(lookup, rows, cols, length, sine_range))


def lookup_coordinates(
    lookup: DirectionLookup,
    rows: list[FloatArray],
    cols: list[FloatArray],
    length: NDArray[np.float32],
    sine_range: tuple[float, float] | None = None,
) -> tuple[NDArray[np.float32], NDArray[np.float32], NDArray[np.uint8] | None]:
    """Where rays (as :func:`lookup_map` takes them) read the lookup: texel x and y, (H, W) float32, and validity.

    Validity is 255 where the ray's elevation is in the table's range, 0
    elsewhere; None when ``sine_range`` shows every ray is in it. x and y are
    this thread's scratch memory, good until its next map of the same size.
    """

    # Scratch memory; the last two (read_lookup's u and v) hold K/w meanwhile.
    d_z, x, y, inverse, _ = _scratch(length.shape)

    def component(axis: int, out: NDArray[np.float32]) -> NDArray[np.float32]:
        return np.add(rows[axis].astype(np.float32)[:, None], cols[axis].astype(np.float32)[None, :], out=out)

    low, high = lookup.sine_range
    unchecked = sine_range is not None and low + SINE_MARGIN < sine_range[0] and sine_range[1] < high - SINE_MARGIN
    component(2, d_z)
    # w = |d| + c d_z, then K/w; zero (infinite) only at the unseen pole, which is invalid.
    if lookup.pole < 0:
        np.subtract(length, d_z, out=inverse)
    else:
        np.add(length, d_z, out=inverse)
    valid = None
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        np.divide(np.float32(lookup.scale), inverse, out=inverse)
        if not unchecked:
            q = np.multiply(d_z, inverse, out=d_z)
            valid = np.asarray(cv2.inRange(q, *lookup.q_range), dtype=np.uint8)
        for axis, coordinate in enumerate((x, y)):
            component(axis, coordinate)
            coordinate *= inverse
            coordinate += np.float32(lookup.centre)
    return x, y, valid


_SCRATCH = threading.local()
# Maps up to this many pixels keep their scratch memory (5 x 4 bytes a pixel: 80 MB at most).
SCRATCH_PIXELS = 4_000_000


def _scratch(shape: tuple[int, ...]) -> list[NDArray[np.float32]]:
    """Five float32 arrays of ``shape``, this thread's, kept for its next map of that shape.

    Fresh memory costs page faults on every write, and a moving view asks for
    map after map of one size. Only maps up to ``SCRATCH_PIXELS`` keep theirs.
    """
    kept = getattr(_SCRATCH, "arrays", [])
    if kept and kept[0].shape == shape:
        return kept
    arrays = [np.empty(shape, dtype=np.float32) for _ in range(5)]
    _SCRATCH.arrays = arrays if math.prod(shape) <= SCRATCH_PIXELS else []
    return arrays


def read_lookup(
    lookup: DirectionLookup, x: NDArray[np.float32], y: NDArray[np.float32], valid: NDArray[np.uint8] | None
) -> NDArray[np.float32]:
    """The (H, W, 2) map read from the lookup at texels (x, y); NaN where not ``valid`` or off the image.

    ``valid`` (255 or 0; None: all valid) is overwritten.
    """
    _, _, _, u, v = _scratch(x.shape)
    for image, out in ((lookup.u, u), (lookup.v, v)):
        cv2.remap(image, x, y, cv2.INTER_LINEAR, dst=out, borderMode=cv2.BORDER_CONSTANT, borderValue=math.nan)
    if lookup.image_size is not None:
        width, height = lookup.image_size
        for coordinate, top in ((u, width - 0.5), (v, height - 0.5)):
            inside = np.asarray(cv2.inRange(coordinate, -0.5, top), dtype=np.uint8)
            valid = inside if valid is None else np.bitwise_and(valid, inside, out=valid)
    if valid is not None and cv2.countNonZero(valid) < valid.size:
        nan_where_invalid = np.asarray(cv2.LUT(valid, _NAN_UNLESS_VALID), dtype=np.float32)
        u += nan_where_invalid
        v += nan_where_invalid
    return np.asarray(cv2.merge([u, v]), dtype=np.float32)


def _remap(image: NDArray[np.float32], x: NDArray[np.float32], y: NDArray[np.float32]) -> NDArray[np.float32]:
    """``image`` read bilinearly at (x, y), NaN off it."""
    out = cv2.remap(image, x, y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=math.nan)
    return np.asarray(out, dtype=np.float32)
