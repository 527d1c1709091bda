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
- **Accuracy.** Texels are ``step`` rad apart at the visible pole and closer
  elsewhere. The step is chosen per table: the coarsest of ``LOOKUP_STEPS``
  (a small lookup is read faster: more of it stays in the cache) whose
  reading differs from the exact sampling by at most ``LOOKUP_ERROR_PX`` on
  ``ERROR_RAYS`` seeded random rays over the table's range. The difference is
  float32 rounding plus the lookup's interpolation, which grows with the image's
  pixels per radian and the mirror's curvature (``bench/bench_views.py``
  prints the largest difference over whole views; the tests bound it on
  several cameras).
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
from functools import cached_property

import cv2
import numpy as np
from numpy.typing import NDArray

from ..geometry import TWO_PI, FloatArray, inside_image
from ..strips import in_strips
from ..table.table import PanoMappingTable

# Texel spacings (rad) at the visible pole, tried coarsest first; spacing shrinks towards the far
# edge. Over whole views on the test cameras (800 px images), the worst difference from the exact
# maps is 0.0035 px at 1e-2 and 0.0021 px at 5e-3 (a hyperbolic mirror); 0.0006 px at either on the
# bench's 1920 px parabolic image. Halving the step quadruples the memory (2.2 MB at 1e-2, 9 MB at
# 5e-3 for a table reaching 15 deg above the horizon) and reads more slowly (fewer cache hits:
# a 1280 x 720 view reads a 1e-2 lookup in 25-40% less time than a 5e-3 one).
LOOKUP_STEPS = (1e-2, 5e-3, 2.5e-3)
# The largest difference from the exact sampling a step may show on the random rays (px): a third
# of the 0.01 px the quick maps promise, as whole views reach a little further than the rays see.
LOOKUP_ERROR_PX = 3e-3
ERROR_RAYS = 20_000
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

    @cached_property
    def transposed(self) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
        """u and v transposed (read-only), made on first use: for views whose rows run along the lookup's columns."""
        images = tuple(np.ascontiguousarray(image.T) for image in (self.u, self.v))
        for image in images:
            image.setflags(write=False)
        return images[0], images[1]


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
        _LOOKUPS[key] = fitting_lookup(table)
        weakref.finalize(table, _LOOKUPS.pop, key, None)
    return _LOOKUPS[key]


def fitting_lookup(table: PanoMappingTable) -> DirectionLookup | None:
    """The lookup of the coarsest of ``LOOKUP_STEPS`` within ``LOOKUP_ERROR_PX`` of the exact sampling.

    Else the finest that is not too large; None when even the coarsest is.
    """
    lookup = None
    for step in LOOKUP_STEPS:
        finer = make_lookup(table, step)
        if finer is None:  # too large: keep the last one that was not
            break
        lookup = finer
        if lookup_error(lookup, table) <= LOOKUP_ERROR_PX:
            break
    return lookup


def lookup_error(lookup: DirectionLookup, table: PanoMappingTable, rays: int = ERROR_RAYS) -> float:
    """Largest difference (px) between reading ``lookup`` and sampling ``table`` exactly, over seeded random rays.

    The rays are uniform in azimuth and in elevation over the table's range;
    only rays with a source both ways count.
    """
    rng = np.random.default_rng(0)
    rho_s, rho_e = table.elevation_range
    theta = rng.uniform(0.0, TWO_PI, rays)
    rho = rng.uniform(rho_s, rho_e, rays)
    d = np.stack([np.cos(rho) * np.cos(theta), np.cos(rho) * np.sin(theta), np.sin(rho)])
    with np.errstate(divide="ignore", invalid="ignore"):
        texels = lookup.centre + lookup.scale * d[:2] / (1.0 + lookup.pole * d[2])
    x, y = (np.ascontiguousarray(values, dtype=np.float32).reshape(1, -1) for values in texels)
    read = np.stack([_remap(image, x, y)[0] for image in (lookup.u, lookup.v)], axis=-1)
    exact = table.sample(theta, rho)
    both = np.isfinite(read).all(axis=-1) & np.isfinite(exact).all(axis=-1)
    return float(np.max(np.abs(read - exact)[both])) if both.any() else 0.0


def make_lookup(table: PanoMappingTable, step: float = LOOKUP_STEPS[0]) -> DirectionLookup | None:
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


def row_sine_bounds(
    rows: list[FloatArray], direction: FloatArray, offsets: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Per row, bounds of the sine of elevation ``d_z/|d|`` over rays ``d = a + x*b`` (a view's row of pixels).

    Parameters
    ----------
    rows : three (H,) arrays
        The components of ``a``, one per row (world axes).
    direction : (3,) array
        ``b``, the same for every row (nonzero).
    offsets : (W,) array
        The pixels' x.

    Returns
    -------
    low, high : (H,) float64 ndarrays
        Along a line, ``d_z/|d|`` has at most one stationary point,
        ``x* = (a_z (a.b) - b_z |a|^2) / (b_z (a.b) - a_z |b|^2)``; the
        extremes over the segment of pixels are at its ends or there.
    """
    a_x, a_y, a_z = (np.asarray(values, dtype=np.float64) for values in rows)
    b_x, b_y, b_z = (float(value) for value in direction)
    x_first, x_last = float(np.min(offsets)), float(np.max(offsets))
    a_b = a_x * b_x + a_y * b_y + a_z * b_z
    a_a = a_x * a_x + a_y * a_y + a_z * a_z
    b_b = b_x * b_x + b_y * b_y + b_z * b_z
    with np.errstate(divide="ignore", invalid="ignore"):
        stationary = (a_z * a_b - b_z * a_a) / (b_z * a_b - a_z * b_b)
    stationary = np.where(np.isfinite(stationary), np.clip(stationary, x_first, x_last), x_first)

    def sine(x: FloatArray | float) -> FloatArray:
        # |a + x b|^2 = |a|^2 + 2 x (a.b) + x^2 |b|^2
        return np.asarray((a_z + x * b_z) / np.sqrt(a_a + x * (2.0 * a_b + x * b_b)), dtype=np.float64)

    ends, middle = (sine(x_first), sine(x_last)), sine(stationary)
    return np.minimum(np.minimum(*ends), middle), np.maximum(np.maximum(*ends), middle)


def lookup_map(
    lookup: DirectionLookup,
    rows: list[FloatArray],
    cols: list[FloatArray],
    length: NDArray[np.float32],
    row_sines: tuple[FloatArray, FloatArray] | None = None,
) -> NDArray[np.float32]:
    """The (H, W, 2) float32 map of rays ``d[l, k, a] = rows[a][l] + cols[a][k]`` (world axes), NaN without a source.

    The rows are cut into strips (:func:`~panomap.strips.in_strips`), each
    made in its own thread.

    Parameters
    ----------
    lookup : DirectionLookup
    rows : three (H,) arrays
    cols : three (W,) arrays
        The rays' x, y and z components as a row term plus a column term (as
        :func:`~panomap.views.grid.grid_angles` takes them).
    length : (H, W) float32 ndarray
        ``|d|`` of every ray.
    row_sines : two (H,) arrays, optional
        Per row, bounds of ``d_z/|d|`` (:func:`row_sine_bounds`), when the view
        knows them: rows well inside the table's range need no check of their
        elevation.
    """
    height, width = length.shape
    out = np.empty((height, width, 2), dtype=np.float32)
    across = runs_across(lookup, [values[height // 2] for values in rows], cols, length[height // 2])

    def strip(start: int, stop: int) -> None:
        strip_rows = [values[start:stop] for values in rows]
        strip_sines = None if row_sines is None else (row_sines[0][start:stop], row_sines[1][start:stop])
        texels = lookup_coordinates(lookup, strip_rows, cols, length[start:stop], strip_sines)
        read_lookup(lookup, *texels, out=out[start:stop], across=across)

    in_strips(height, strip)
    return out


def runs_across(lookup: DirectionLookup, row: list[float], cols: list[FloatArray], length: NDArray[np.float32]) -> bool:
    """Whether a view's row of rays ``row[a] + cols[a][k]`` runs more along the lookup's columns than its rows.

    ``cv2.remap`` reads a 1-channel image faster when consecutive pixels read
    along its rows (fewer cache lines): such views read the transposed lookup
    (25% less time for a straight-down view on a 1920 px image).
    """
    d = [row[axis] + np.asarray(cols[axis], dtype=np.float64) for axis in range(3)]
    with np.errstate(divide="ignore", invalid="ignore"):
        w = np.asarray(length, dtype=np.float64) + lookup.pole * d[2]
        steps = [np.nansum(np.abs(np.diff(d[axis] / w))) for axis in (0, 1)]
    return bool(steps[1] > steps[0])


@dataclass(frozen=True)
class RowCheck:
    """The result of the elevation check on the rows that needed it: rows ``start..start + len(valid)``.

    ``valid`` is (rows, W) uint8: 255 where the ray's elevation is in the
    table's range, 0 elsewhere. The other rows are all in range.
    """

    start: int
    valid: NDArray[np.uint8]


def lookup_coordinates(
    lookup: DirectionLookup,
    rows: list[FloatArray],
    cols: list[FloatArray],
    length: NDArray[np.float32],
    row_sines: tuple[FloatArray, FloatArray] | None = None,
) -> tuple[NDArray[np.float32], NDArray[np.float32], RowCheck | None]:
    """Where rays (as :func:`lookup_map` takes them) read the lookup: texel x and y, (H, W) float32, and the check.

    ``X = c0 + K d_x/w`` (and Y alike) with ``w = |d| + c d_z``: eight passes
    over the rays. The elevation check (``K d_z/w`` within the range of the
    table's ends) runs on the rows that ``row_sines`` does not show inside the
    range, all of them without it; None when no row needs it. x and y are this
    thread's scratch memory, good until its next map of the same size.
    """
    w, x, y, _ = _scratch(length.shape)

    def numerator(axis: int, factor: float, out: NDArray[np.float32]) -> NDArray[np.float32]:
        row = (factor * np.asarray(rows[axis], dtype=np.float64)).astype(np.float32)
        col = (factor * np.asarray(cols[axis], dtype=np.float64)).astype(np.float32)
        return np.add(row[:, None], col[None, :], out=out)

    # w = |d| + c d_z; zero (infinite texels) only at the unseen pole, which is invalid.
    np.add(length, numerator(2, lookup.pole, w), out=w)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        check = _check_rows(lookup, rows, cols, w, row_sines)
        for axis, coordinate in enumerate((x, y)):
            numerator(axis, lookup.scale, coordinate)
            np.divide(coordinate, w, out=coordinate)
            coordinate += np.float32(lookup.centre)
    return x, y, check


def _check_rows(
    lookup: DirectionLookup,
    rows: list[FloatArray],
    cols: list[FloatArray],
    w: NDArray[np.float32],
    row_sines: tuple[FloatArray, FloatArray] | None,
) -> RowCheck | None:
    """The elevation check of :func:`lookup_coordinates` on the rows that need it (one span of rows)."""
    low, high = lookup.sine_range
    if row_sines is None:
        need = np.ones(w.shape[0], dtype=bool)
    else:
        need = (row_sines[0] <= low + SINE_MARGIN) | (row_sines[1] >= high - SINE_MARGIN)
    if not need.any():
        return None
    first = int(np.argmax(need))
    stop = len(need) - int(np.argmax(need[::-1]))
    span = [values[first:stop] for values in rows]
    q = np.add(
        (lookup.scale * np.asarray(span[2], dtype=np.float64)).astype(np.float32)[:, None],
        (lookup.scale * np.asarray(cols[2], dtype=np.float64)).astype(np.float32)[None, :],
    )
    np.divide(q, w[first:stop], out=q)
    return RowCheck(first, np.asarray(cv2.inRange(q, *lookup.q_range), dtype=np.uint8))


_SCRATCH = threading.local()
# Maps up to this many pixels keep their scratch memory (4 x 4 bytes a pixel: 64 MB at most).
SCRATCH_PIXELS = 4_000_000


def _scratch(shape: tuple[int, ...]) -> list[NDArray[np.float32]]:
    """Four float32 arrays of ``shape``, this thread's, kept for its next map of that shape.

    Fresh memory costs page faults on every write, and a moving view asks for
    map after map of one size. Only maps up to ``SCRATCH_PIXELS`` keep theirs.
    The first holds w while the texels are worked out, then the map's u (less
    memory to go through the caches).
    """
    kept = getattr(_SCRATCH, "arrays", [])
    if kept and kept[0].shape == shape:
        return kept
    arrays = [np.empty(shape, dtype=np.float32) for _ in range(4)]
    _SCRATCH.arrays = arrays if math.prod(shape) <= SCRATCH_PIXELS else []
    return arrays


def read_lookup(
    lookup: DirectionLookup,
    x: NDArray[np.float32],
    y: NDArray[np.float32],
    check: RowCheck | None,
    out: NDArray[np.float32] | None = None,
    across: bool = False,
) -> NDArray[np.float32]:
    """The (H, W, 2) map read from the lookup at texels (x, y); NaN where ``check`` fails or off the image.

    The map is written into ``out`` (a C-contiguous (H, W, 2) float32 array)
    when given. ``across`` reads the transposed lookup (the same values; see
    :func:`runs_across`).
    """
    u, _, _, v = _scratch(x.shape)
    images, map_x, map_y = (lookup.transposed, y, x) if across else ((lookup.u, lookup.v), x, y)
    for image, read in zip(images, (u, v), strict=True):
        cv2.remap(image, map_x, map_y, cv2.INTER_LINEAR, dst=read, borderMode=cv2.BORDER_CONSTANT, borderValue=math.nan)
    start, valid = (0, None) if check is None else (check.start, check.valid)
    if lookup.image_size is not None:
        width, height = lookup.image_size
        inside = np.asarray(cv2.inRange(u, -0.5, width - 0.5), dtype=np.uint8)
        np.bitwise_and(inside, np.asarray(cv2.inRange(v, -0.5, height - 0.5), dtype=np.uint8), out=inside)
        if valid is not None:
            np.bitwise_and(inside[start : start + len(valid)], valid, out=inside[start : start + len(valid)])
        start, valid = 0, inside
    if valid is not None and cv2.countNonZero(valid) < valid.size:
        nan_where_invalid = np.asarray(cv2.LUT(valid, _NAN_UNLESS_VALID), dtype=np.float32)
        rows = slice(start, start + len(valid))
        np.add(u[rows], nan_where_invalid, out=u[rows])
        np.add(v[rows], nan_where_invalid, out=v[rows])
    if out is None:
        return np.asarray(cv2.merge([u, v]), dtype=np.float32)
    cv2.merge([u, v], dst=out)
    return out


def _remap(image: NDArray[np.float32], x: NDArray[np.float32], y: NDArray[np.float32]) -> NDArray[np.float32]:
    """``image`` read bilinearly at (x, y), NaN off it."""
    out = cv2.remap(image, x, y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=math.nan)
    return np.asarray(out, dtype=np.float32)
