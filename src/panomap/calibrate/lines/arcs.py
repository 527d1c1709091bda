"""Edge arcs of an omni-image: the candidate images of straight world lines.

Convention: pixel (u, v), u the column, v the row, the centre of the top-left pixel at (0, 0)
(docs/conventions.md); radii from the image centre in px.

Method:

1. **Edges.** The grey image is smoothed (Gaussian, ``sigma`` px); its gradient (grey levels / px)
   feeds Canny's non-maximum suppression and hysteresis, with thresholds from the image's own
   gradient statistics in the annulus (the sensor noise and texture set the floor).
2. **Annulus.** Edge pixels count only between the cut-off disc (the camera's own reflection) and
   the image circle, a margin inside both, and a margin inside the frame where it cuts the circle.
3. **Chains.** The edge map is thinned (staircase corners dropped), junction pixels (three or more
   neighbours: T-junctions, checker corners, crossings) removed, and the simple paths left are
   walked end to end.
4. **Sub-pixel.** Each edge pixel moves along its gradient to the vertex of a parabola through the
   gradient magnitude at -1, 0, +1 px.
5. **Corners.** A chain is cut where it turns by more than ``CORNER_DEG`` over ``CORNER_SPAN_PX`` on
   either side (a room's corner, the bend of an L).
6. **Joins.** Pieces whose ends face each other across a small gap (a junction removed in step 3),
   in line and with the same direction, are joined, so a line crossing checker corners or
   T-junctions comes out whole.
7. **Filters.** Chains shorter than ``min_length_px`` or weaker than the edge threshold are dropped.

Straightness is not decided here: that needs the camera model (see ``fit.py``).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from ..circles import ImageCircles

# scipy is imported where it is used: its import would cost every command (a video's start-up too) 0.4 s.

#: Turning angle (deg) over CORNER_SPAN_PX on either side of a point above which a chain is cut there.
CORNER_DEG = 10.0
#: Half-span (px) over which the turning angle is measured.
CORNER_SPAN_PX = 6
#: Largest gap (px) between two pieces that are joined.
JOIN_GAP_PX = 16.0
#: Largest angle (deg) between the two pieces' directions at a join.
JOIN_ANGLE_DEG = 6.0
#: Largest offset (px) of either end from the other piece's tangent at a join.
JOIN_OFFSET_PX = 1.5
#: Points (at the ends) over which a piece's end tangent is measured.
END_POINTS = 10
#: Points left out at both ends of every chain (where it bends into a junction it was cut from).
END_TRIM_POINTS = 2
#: Fewest points of a piece between junctions and corners that takes part in the joins (a checkerboard's
#: square side between two crossings).
MIN_PIECE_POINTS = 4
#: The strong edge threshold: this many times the median gradient magnitude of the annulus, and
#: at least MIN_EDGE_GRADIENT grey levels / px; the weak one is half of it.
EDGE_THRESHOLD_MEDIANS = 4.0
MIN_EDGE_GRADIENT = 4.0
#: The smoothing (px) of the working image. A large image circle is smoothed over ``R/700`` px: the
#: edges are searched in the image averaged over blocks of k x k pixels, k as large as keeps this much
#: smoothing at the smaller scale (its detail is below the smoothing already; the memory is k^2 less).
WORKING_SIGMA_PX = 2.0
#: Rows of the image averaged at a time (a multiple of k): bounds the scratch memory of the block average.
BLOCK_ROWS = 256

_NEIGHBOURS = ((-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1))


@dataclass(frozen=True)
class EdgeArc:
    """One smooth edge curve of an omni-image: a candidate image of one straight world line.

    Attributes
    ----------
    pixels : (N, 2) float64, px
        Sub-pixel edge points ``[u, v]`` ordered along the curve, N >= 8.
    image_index : int
        Which input image, 0-based.
    contrast : float
        Median gradient magnitude across the edge (grey levels / px).
    """

    pixels: NDArray[np.float64]
    image_index: int
    contrast: float

    @property
    def length_px(self) -> float:
        """Length of the curve along its points (px)."""
        return float(np.sum(np.hypot(*np.diff(self.pixels, axis=0).T)))


def _grey(image: NDArray[np.generic]) -> NDArray[np.float32]:
    """(H, W) float32 grey levels of an (H, W) or (H, W, 3) image."""
    img = np.asarray(image)
    if img.ndim == 3:
        return np.asarray(img[..., :3], dtype=np.float32).mean(axis=2).astype(np.float32)
    return img.astype(np.float32)


def working_factor(sigma_px: float) -> int:
    """k: the edges of an image smoothed over ``sigma_px`` are searched in its k x k block average, whose
    box (k/sqrt(12) px) and smoothing of at least WORKING_SIGMA_PX (of its own px) make up ``sigma_px``."""
    return max(1, math.floor(sigma_px / math.sqrt(WORKING_SIGMA_PX**2 + 1.0 / 12.0)))


def block_grey(image: NDArray[np.generic], k: int) -> NDArray[np.float32]:
    """(H // k, W // k) float32 grey levels: the mean of the channels over each k x k block (the last
    ``H % k`` rows and ``W % k`` columns left out), about BLOCK_ROWS image rows at a time. k = 1: :func:`_grey`."""
    if k == 1:
        return _grey(image)
    img = np.asarray(image)
    h, w = img.shape[0] // k, img.shape[1] // k
    out = np.empty((h, w), dtype=np.float32)
    step = max(1, BLOCK_ROWS // k)  # working rows a band
    for start in range(0, h, step):
        stop = min(start + step, h)
        band = np.asarray(img[start * k : stop * k, : w * k], dtype=np.float32)
        band = band.reshape(stop - start, k, w, k, -1)
        out[start:stop] = band.mean(axis=(1, 3, 4))
    return out


def usable_mask(shape: tuple[int, int], circles: ImageCircles, margin_px: float, factor: int = 1) -> NDArray[np.bool_]:
    """(H, W) bool: pixels between the cut-off disc and the image circle, ``margin_px`` inside both and
    inside the frame's edges. With ``factor`` k, the pixels of the k x k block average (:func:`block_grey`):
    ``shape`` and ``margin_px`` in its pixels, the circles in the image's."""
    h, w = shape
    u0, v0 = ((c - (factor - 1) / 2) / factor for c in circles.centre)
    vv, uu = np.mgrid[0:h, 0:w]
    r = np.hypot(uu - u0, vv - v0)
    inner = 0.0 if circles.cutoff is None else circles.cutoff.radius / factor
    m = math.ceil(margin_px)
    frame = np.zeros((h, w), dtype=bool)
    frame[m : h - m, m : w - m] = True
    return np.asarray((r > inner + margin_px) & (r < circles.outer.radius / factor - margin_px) & frame)


def _thin(edges: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """Drop the corner pixels of staircases (a pixel with two 4-neighbours at right angles whose
    opposite side is empty): the edge stays 8-connected and one pixel wide."""
    base = np.array([[0, 1, 0], [1, 1, -1], [0, -1, -1]], dtype=np.int32)
    out = edges.copy()
    for turn in range(4):
        kernel = np.rot90(base, turn).copy()
        hit = cv2.morphologyEx(out, cv2.MORPH_HITMISS, kernel)
        out[hit > 0] = 0
    return out


def _walk_chains(edges: NDArray[np.uint8]) -> list[NDArray[np.int64]]:
    """Simple paths of an edge map whose pixels have at most two 8-neighbours: each (n, 2) [row, col]
    ordered along the path (closed loops opened at one pixel)."""
    h, w = edges.shape
    rows, cols = np.nonzero(edges)
    n = rows.size
    if n == 0:
        return []
    index = np.full((h + 2, w + 2), -1, dtype=np.int64)
    index[rows + 1, cols + 1] = np.arange(n)
    nb = np.stack([index[rows + 1 + dr, cols + 1 + dc] for dr, dc in _NEIGHBOURS], axis=1)
    nb = -np.sort(-nb, axis=1)[:, :2]  # the (at most two) neighbours first
    count = (nb >= 0).sum(axis=1)
    first, second = nb[:, 0].tolist(), nb[:, 1].tolist()
    visited = bytearray(n)
    chains: list[NDArray[np.int64]] = []
    starts = np.concatenate([np.flatnonzero(count == 1), np.flatnonzero(count == 2)])
    for start in starts.tolist():
        if visited[start]:
            continue
        path = [start]
        visited[start] = 1
        prev, cur = -1, start
        while True:
            a, b = first[cur], second[cur]
            if a >= 0 and a != prev and not visited[a]:
                nxt = a
            elif b >= 0 and b != prev and not visited[b]:
                nxt = b
            else:
                nxt = -1
            if nxt < 0:
                break
            visited[nxt] = 1
            path.append(nxt)
            prev, cur = cur, nxt
        idx = np.asarray(path, dtype=np.int64)
        chains.append(np.stack([rows[idx], cols[idx]], axis=1))
    return chains


def _bilinear(field: NDArray[np.float32], u: NDArray[np.float64], v: NDArray[np.float64]) -> NDArray[np.float64]:
    """``field`` (H, W) at (u, v) (px), bilinear in float64; clamped at the border."""
    h, w = field.shape
    u = np.clip(u, 0.0, w - 1.0)
    v = np.clip(v, 0.0, h - 1.0)
    u0 = np.minimum(np.floor(u).astype(np.int64), w - 2)
    v0 = np.minimum(np.floor(v).astype(np.int64), h - 2)
    fu, fv = u - u0, v - v0
    top = field[v0, u0] * (1.0 - fu) + field[v0, u0 + 1] * fu
    bottom = field[v0 + 1, u0] * (1.0 - fu) + field[v0 + 1, u0 + 1] * fu
    return np.asarray(top * (1.0 - fv) + bottom * fv)


def _subpixel(
    rows: NDArray[np.int64],
    cols: NDArray[np.int64],
    gx: NDArray[np.float32],
    gy: NDArray[np.float32],
    mag: NDArray[np.float32],
) -> NDArray[np.float64]:
    """(n, 2) [u, v]: each edge pixel moved along its gradient to the peak of the gradient magnitude (a
    parabola through -1, 0, +1 px, then once more about the point found: an edge pixel left beside the
    peak by the thinning is pulled back to it)."""
    g = np.stack([gx[rows, cols], gy[rows, cols]], axis=1).astype(np.float64)
    g /= np.maximum(np.hypot(g[:, 0], g[:, 1]), 1e-12)[:, None]
    u, v = cols.astype(np.float64), rows.astype(np.float64)
    total = np.zeros(len(u))
    for _ in range(2):
        cu, cv = u + total * g[:, 0], v + total * g[:, 1]
        m0 = _bilinear(mag, cu, cv)
        mp = _bilinear(mag, cu + g[:, 0], cv + g[:, 1])
        mm = _bilinear(mag, cu - g[:, 0], cv - g[:, 1])
        denom = mm - 2.0 * m0 + mp
        peaked = denom < -1e-9
        t = np.where(peaked, 0.5 * (mm - mp) / np.where(peaked, denom, -1.0), 0.0)
        total = np.clip(total + np.clip(t, -1.0, 1.0), -1.5, 1.5)
    return np.stack([u + total * g[:, 0], v + total * g[:, 1]], axis=1)


def _corner_cuts(points: NDArray[np.float64], span: int, limit_deg: float) -> list[int]:
    """Indices where the chain turns by more than ``limit_deg`` over ``span`` points on either side (the
    local maxima of the turning angle above it)."""
    n = len(points)
    if n < 2 * span + 1:
        return []
    back = points[span:-span] - points[: n - 2 * span]
    ahead = points[2 * span :] - points[span:-span]
    cross = back[:, 0] * ahead[:, 1] - back[:, 1] * ahead[:, 0]
    dot = np.sum(back * ahead, axis=1)
    turn = np.degrees(np.abs(np.arctan2(cross, dot)))
    over = turn > limit_deg
    cuts: list[int] = []
    i = 0
    while i < len(turn):
        if over[i]:
            j = i
            while j < len(turn) and over[j]:
                j += 1
            cuts.append(span + i + int(np.argmax(turn[i:j])))
            i = j
        else:
            i += 1
    return cuts


def _end_tangent(points: NDArray[np.float64], at_end: bool) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The end point and the unit direction pointing out of the piece there (principal axis of the last
    END_POINTS points)."""
    k = min(END_POINTS, len(points))
    seg = points[-k:] if at_end else points[:k][::-1]
    centred = seg - seg.mean(axis=0)
    _, _, vt = np.linalg.svd(centred, full_matrices=False)
    d = vt[0]
    if float(d @ (seg[-1] - seg[0])) < 0:
        d = -d
    return seg[-1], d


def _join(pieces: list[NDArray[np.float64]], gap_px: float) -> list[NDArray[np.float64]]:
    """Join pieces whose ends face each other across a gap of at most ``gap_px``, in line."""
    if len(pieces) < 2:
        return pieces
    ends = []  # (piece, at_end) for node 2*i (start) and 2*i+1 (end)
    pts = np.empty((2 * len(pieces), 2))
    dirs = np.empty((2 * len(pieces), 2))
    for i, p in enumerate(pieces):
        for at_end in (False, True):
            e, d = _end_tangent(p, at_end)
            node = 2 * i + int(at_end)
            pts[node], dirs[node] = e, d
            ends.append((i, at_end))
    from scipy.spatial import cKDTree

    tree = cKDTree(pts)
    pairs = tree.query_pairs(gap_px, output_type="ndarray")
    cos_lim = math.cos(math.radians(JOIN_ANGLE_DEG))
    candidates = []
    for a, b in pairs.tolist():
        if a // 2 == b // 2:
            continue
        da, db = dirs[a], dirs[b]
        if float(da @ -db) < cos_lim:
            continue
        gap = pts[b] - pts[a]
        off_a = abs(da[0] * gap[1] - da[1] * gap[0])
        off_b = abs(db[0] * gap[1] - db[1] * gap[0])
        if max(off_a, off_b) > JOIN_OFFSET_PX:
            continue
        dist = float(np.hypot(*gap))
        if dist > 1.5 and (float(da @ gap) < 0.8 * dist or float(-db @ gap) < 0.8 * dist):
            continue
        candidates.append((off_a + off_b + 0.05 * dist, a, b))
    candidates.sort()
    partner = np.full(len(pts), -1, dtype=np.int64)
    # union-find over pieces, so that no ring of pieces forms
    parent = list(range(len(pieces)))

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for _, a, b in candidates:
        if partner[a] >= 0 or partner[b] >= 0:
            continue
        ra, rb = root(a // 2), root(b // 2)
        if ra == rb:
            continue
        parent[ra] = rb
        partner[a], partner[b] = b, a
    out: list[NDArray[np.float64]] = []
    used = np.zeros(len(pieces), dtype=bool)
    for i in range(len(pieces)):
        if used[i] or (partner[2 * i] >= 0 and partner[2 * i + 1] >= 0):
            continue
        # start at a piece with a free end: walk through partners
        node = 2 * i if partner[2 * i] < 0 else 2 * i + 1  # the free end
        parts = []
        while True:
            piece = node // 2
            used[piece] = True
            p = pieces[piece]
            parts.append(p if node % 2 == 0 else p[::-1])
            other = node ^ 1
            nxt = int(partner[other])
            if nxt < 0:
                break
            node = nxt
        out.append(np.concatenate(parts, axis=0))
    return out


def find_arcs(
    image: NDArray[np.generic],
    circles: ImageCircles,
    *,
    image_index: int = 0,
    sigma: float | None = None,
    min_length_px: float | None = None,
) -> list[EdgeArc]:
    """Edge arcs inside the usable annulus of ``image`` ((H, W) or (H, W, 3) uint8).

    Parameters
    ----------
    image : (H, W) or (H, W, 3) array
        The omni-image.
    circles : ImageCircles
        Its image circle and cut-off disc (``find_image_circles``).
    image_index : int
        Stored in each arc: which input image it came from.
    sigma : float or None
        Smoothing (px) before the gradient; default ``max(1.2, R/700)``, R the image circle's radius.
        Where it is wide, the edges are searched in the image's k x k block average
        (:func:`working_factor`), with the smoothing that makes up ``sigma``: a 16000 x 16000 image of an
        8000 px circle is searched as a 3200 x 3200 one (k = 5); its points stay within a few hundredths
        of a pixel of the full-resolution ones (``tests/test_line_bounds.py``).
    min_length_px : float or None
        Shortest arc kept (px along the curve); default ``max(24, R/25)``.

    Returns
    -------
    list of EdgeArc
        Longest first. Between the cut-off disc and the image circle, a margin inside both and inside
        the frame; split at corners, joined across junctions; each at least ``min_length_px`` long.
    """
    radius = float(circles.outer.radius)
    s = max(1.2, radius / 700.0) if sigma is None else float(sigma)
    min_len = max(24.0, radius / 25.0) if min_length_px is None else float(min_length_px)
    k = working_factor(s)
    grey = block_grey(image, k)
    h, w = grey.shape
    # In the working image's px: the smoothing left after the block's own box, the lengths.
    s_work = math.sqrt(max(s * s - (k * k - 1) / 12.0, 0.0)) / k
    blur = cv2.GaussianBlur(grey, (0, 0), s_work)
    del grey
    gx = np.asarray(cv2.Sobel(blur, cv2.CV_32F, 1, 0, ksize=3, scale=0.125), dtype=np.float32)
    gy = np.asarray(cv2.Sobel(blur, cv2.CV_32F, 0, 1, ksize=3, scale=0.125), dtype=np.float32)
    del blur
    mag = np.asarray(cv2.magnitude(gx, gy), dtype=np.float32)
    mask = usable_mask((h, w), circles, margin_px=(3.0 + 3.0 * s) / k, factor=k)
    if not mask.any():
        return []
    level = float(np.median(mag[mask]))
    # Gradients per working px are k times those per image px.
    high = max(k * MIN_EDGE_GRADIENT, EDGE_THRESHOLD_MEDIANS * level)
    unit = 16.0  # int16 gradients at 1/16 grey level per px
    dx = np.clip(np.rint(gx * unit), -32767, 32767).astype(np.int16)
    dy = np.clip(np.rint(gy * unit), -32767, 32767).astype(np.int16)
    edges = cv2.Canny(dx, dy, 0.5 * high * unit, high * unit, L2gradient=True)
    edges[~mask] = 0
    edges = _thin((edges > 0).astype(np.uint8))
    count = cv2.filter2D(edges, cv2.CV_16S, np.ones((3, 3), np.float32), borderType=cv2.BORDER_CONSTANT) - edges
    edges[(edges > 0) & (count >= 3)] = 0
    pieces: list[NDArray[np.float64]] = []
    short = MIN_PIECE_POINTS
    for chain in _walk_chains(edges):
        if len(chain) < short + 2 * END_TRIM_POINTS:
            continue
        pts = _subpixel(chain[:, 0], chain[:, 1], gx, gy, mag)
        # an edge bends into a junction or a corner's rounding over its last pixels: leave them out
        pts = pts[END_TRIM_POINTS : len(pts) - END_TRIM_POINTS]
        cuts = _corner_cuts(pts, CORNER_SPAN_PX, CORNER_DEG)
        bounds = [0, *cuts, len(pts)]
        for a, b in itertools.pairwise(bounds):
            # leave out the corner's own points on both sides
            a2 = a + (2 if a > 0 else 0)
            b2 = b - (2 if b < len(pts) else 0)
            if b2 - a2 >= short:
                pieces.append(pts[a2:b2])
    pieces = _join(pieces, JOIN_GAP_PX)
    arcs: list[EdgeArc] = []
    for p in pieces:
        length = float(np.sum(np.hypot(*np.diff(p, axis=0).T)))
        if k * length < min_len or len(p) < 8:
            continue
        contrast = float(np.median(_bilinear(mag, p[:, 0], p[:, 1])))
        if contrast < 0.5 * high:
            continue
        # Back to the image's px: a working pixel's centre is the centre of its block.
        pixels = k * np.asarray(p, dtype=np.float64) + (k - 1) / 2.0
        arcs.append(EdgeArc(pixels=np.ascontiguousarray(pixels), image_index=int(image_index), contrast=contrast / k))
    arcs.sort(key=lambda a: -len(a.pixels))
    return arcs
