"""Rendered checkerboard scenes, with the true pixels of every inner corner: the ground truth of a fit from
checkerboards found in omni-images.

A person holds printed checkerboards around an omni-camera at O_m (the issue's rendered cameras,
:func:`panomap.simulate.line_scenes.line_camera`: a 190 deg fisheye on a 16:9 sensor, a hyperbolic mirror
on 4:3, tilted), inside the room of :mod:`panomap.simulate.line_scenes`. Each board (:class:`Board`) is a
planar grid of ``cols x rows`` inner corners, ``square`` m apart, with one black-and-white square beyond
the outermost corners and a white margin of one square around that; its pose is known, so the true pixel
of each inner corner is ``camera.project`` of its 3-D point, independently of the renderer, which traces
each pixel's ray (``camera.trace``) to the boards and the room.

Board frame (OpenCV's): x along the rows of corners (column index ``i``), y down the columns (row index
``j``), z away from the camera into the board; inner corner ``(i, j)`` at ``(i*square, j*square, 0)``; the
printed side faces the camera (``-z``). Seen from the camera, x points right and y down, as in an image.
Square ``(floor(x/square), floor(y/square)) = (a, b)`` with ``-1 <= a <= cols - 1`` and
``-1 <= b <= rows - 1`` is black where ``a + b`` is even (so the squares at both ends of the diagonal
through corner (0, 0) are black).

Convention: the camera frame is the frame :meth:`SimulatedCamera.project` takes: world axes (x, y
horizontal, z up), metres, relative to O_m; pixels (u, v), u the column, v the row, the centre of the
top-left pixel at (0, 0); images (H, W) uint8 grey.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from ..errors import PanomapError
from .cameras import SimulatedCamera
from .degrade import noisy_jpeg, vignette
from .line_scenes import ROOM_X, ROOM_Y, ROOM_Z, SCENE_KINDS, room_grey

__all__ = [
    "BOARD_SIZES",
    "Board",
    "BoardScene",
    "BoardTruth",
    "board_poses",
    "render_board_scene",
]

#: Inner-corner counts ``(cols, rows)`` drawn by :func:`board_poses`: boards people print.
BOARD_SIZES = ((9, 6), (8, 6), (7, 5), (7, 6), (6, 4), (10, 7), (8, 5))
#: Grey level (before the sensor) of a board's unprinted back.
_BACK_GREY = 120.0
#: Grey level of the camera's own housing inside the cut-off disc (as the line scenes).
_HOUSING_GREY = 25.0
#: Pixels whose 3 x 3 neighbourhood spans more grey levels than this are supersampled.
_EDGE_LEVELS = 3.0
#: Samples traced per chunk (bounds memory use).
_SAMPLES_PER_CHUNK = 300_000
#: Largest angle (rad) a board's longer side may span, seen from O_m.
_MAX_EXTENT_RAD = math.radians(100.0)
#: Boards stay this far (m) inside the room's walls, floor and ceiling.
_ROOM_CLEARANCE_M = 0.05


@dataclass(frozen=True, eq=False)
class Board:
    """A printed checkerboard and its pose.

    Attributes
    ----------
    cols, rows : int
        Inner corners along x and along y (>= 2 each).
    square : float
        Side of a square (m).
    rotation : (3, 3) float64
        Board axes to the camera frame (columns: the board's x, y, z in the camera frame).
    translation : (3,) float64
        Inner corner (0, 0) in the camera frame (m, relative to O_m).
    """

    cols: int
    rows: int
    square: float
    rotation: NDArray[np.float64]
    translation: NDArray[np.float64]

    def __post_init__(self) -> None:
        if self.cols < 2 or self.rows < 2 or not (math.isfinite(self.square) and self.square > 0):
            raise PanomapError(f"a board needs >= 2 x 2 inner corners and a square > 0, got {self}")
        r = np.asarray(self.rotation, dtype=np.float64)
        if r.shape != (3, 3) or not np.allclose(r.T @ r, np.eye(3), atol=1e-9) or np.linalg.det(r) < 0:
            raise PanomapError(f"a board's rotation must be a (3, 3) rotation, got {self.rotation!r}")
        if np.shape(self.translation) != (3,):
            raise PanomapError(f"a board's translation must have shape (3,), got {np.shape(self.translation)}")

    @property
    def grid(self) -> NDArray[np.int64]:
        """Indices ``(i, j)`` (n, 2) of the inner corners, row by row (``k = j*cols + i``)."""
        j, i = np.mgrid[0 : self.rows, 0 : self.cols]
        return np.stack([i.ravel(), j.ravel()], axis=1).astype(np.int64)

    def points(self, xy: NDArray[np.float64]) -> NDArray[np.float64]:
        """Camera-frame points (n, 3) (m) of board-plane points ``(x, y)`` (n, 2) (m)."""
        xy = np.asarray(xy, dtype=np.float64)
        return np.asarray(xy[:, :1] * self.rotation[:, 0] + xy[:, 1:2] * self.rotation[:, 1] + self.translation)

    @property
    def corners(self) -> NDArray[np.float64]:
        """The inner corners (n, 3) in the camera frame (m), in the order of :attr:`grid`."""
        return self.points(self.grid.astype(np.float64) * self.square)

    def outline(self, per_side: int = 1, margin: bool = True) -> NDArray[np.float64]:
        """Points (4*per_side, 3) (m) round the edge of the board (``margin``) or of its checker, camera frame."""
        lo, hi = (-2.0, self.cols + 1.0) if margin else (-1.0, float(self.cols))
        lo_y, hi_y = (-2.0, self.rows + 1.0) if margin else (-1.0, float(self.rows))
        t = np.arange(per_side) / per_side
        sides = [
            np.stack([lo + (hi - lo) * t, np.full(per_side, lo_y)], axis=1),
            np.stack([np.full(per_side, hi), lo_y + (hi_y - lo_y) * t], axis=1),
            np.stack([hi - (hi - lo) * t, np.full(per_side, hi_y)], axis=1),
            np.stack([np.full(per_side, lo), hi_y - (hi_y - lo_y) * t], axis=1),
        ]
        return self.points(np.concatenate(sides) * self.square)


@dataclass(frozen=True, eq=False)
class BoardTruth:
    """One board as a scene shows it.

    Attributes
    ----------
    pixels : (n, 2) float64
        True pixels ``(u, v)`` of the inner corners (``camera.project`` of :attr:`points`); NaN where the
        camera does not see one (never for boards from :func:`board_poses`; hiding by another board is not
        checked here, :func:`board_poses` keeps their images apart).
    grid : (n, 2) int64
        Their indices ``(i, j)`` on the board.
    points : (n, 3) float64
        Their camera-frame points (m, relative to O_m).
    """

    pixels: NDArray[np.float64]
    grid: NDArray[np.int64]
    points: NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class BoardScene:
    """A rendered checkerboard scene and its truth.

    Attributes
    ----------
    image : (H, W) uint8
        The grey image as the sensor delivers it (vignetting, noise, JPEG).
    clean : (H, W) uint8
        The same before vignetting, noise and JPEG.
    camera : SimulatedCamera
        The true camera.
    boards : tuple of Board
        The boards, as placed.
    truth : tuple of BoardTruth
        Per board, its inner corners.
    """

    image: NDArray[np.uint8]
    clean: NDArray[np.uint8]
    camera: SimulatedCamera
    boards: tuple[Board, ...]
    truth: tuple[BoardTruth, ...]


# -- poses ------------------------------------------------------------------------------------------


def _shown(camera: SimulatedCamera, px: NDArray[np.float64], margin_px: float) -> NDArray[np.bool_]:
    """Which pixels (n, 2) are finite and lie ``margin_px`` inside the frame and the annulus between the
    cut-off disc and the image circle."""
    w, h = camera.image_size
    r = np.hypot(px[:, 0] - camera.centre[0], px[:, 1] - camera.centre[1])
    with np.errstate(invalid="ignore"):
        ok = (r > camera.cutoff_radius + margin_px) & (r < camera.outer_radius - margin_px)
        ok &= (px[:, 0] > margin_px) & (px[:, 0] < w - 1 - margin_px)
        ok &= (px[:, 1] > margin_px) & (px[:, 1] < h - 1 - margin_px)
    return np.asarray(ok & np.all(np.isfinite(px), axis=1))


def _perpendicular(d: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Two unit vectors (3,) completing the unit vector ``d`` (3,) to a right-handed frame."""
    helper = np.array([0.0, 0.0, 1.0]) if abs(d[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    e1 = np.cross(helper, d)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(d, e1)


def _turn(v: NDArray[np.float64], axis: NDArray[np.float64], angle: float) -> NDArray[np.float64]:
    """``v`` (3,) turned by ``angle`` (rad) about the unit ``axis`` (3,) (Rodrigues)."""
    c, s = math.cos(angle), math.sin(angle)
    return np.asarray(v * c + np.cross(axis, v) * s + axis * (axis @ v) * (1.0 - c))


def _magnification(camera: SimulatedCamera, centre: NDArray[np.float64], d: NDArray[np.float64]) -> float:
    """Pixels per radian (geometric mean of two perpendicular directions) of the view about the point
    ``centre`` (3,) seen along the unit ray ``d`` (3,); NaN if unseen."""
    e1, e2 = _perpendicular(d)
    distance = float(np.linalg.norm(centre))
    step = 1e-3
    px = camera.project(np.stack([centre, centre + step * distance * e1, centre + step * distance * e2]))
    k1 = float(np.hypot(*(px[1] - px[0]))) / step
    k2 = float(np.hypot(*(px[2] - px[0]))) / step
    return math.sqrt(k1 * k2)


def _in_room(points: NDArray[np.float64]) -> bool:
    """Whether every point (n, 3) lies inside the line scenes' room, clear of its surfaces."""
    c = _ROOM_CLEARANCE_M
    return bool(
        np.all(
            (points[:, 0] > ROOM_X[0] + c)
            & (points[:, 0] < ROOM_X[1] - c)
            & (points[:, 1] > ROOM_Y[0] + c)
            & (points[:, 1] < ROOM_Y[1] - c)
            & (points[:, 2] > ROOM_Z[0] + c)
            & (points[:, 2] < ROOM_Z[1] - c)
        )
    )


def _footprint(camera: SimulatedCamera, board: Board) -> tuple[NDArray[np.float64], float]:
    """Centre (2,) and radius (px) of a disc holding the image of the board with its margin (where seen)."""
    px = camera.project(board.outline(per_side=16))
    px = px[np.all(np.isfinite(px), axis=1)]
    middle = px.mean(axis=0)
    return middle, float(np.max(np.hypot(*(px - middle).T)))


def _pose_candidate(
    camera: SimulatedCamera,
    rng: np.random.Generator,
    phi_range: tuple[float, float],
    sizes: tuple[tuple[int, int], ...],
    span: tuple[float, float],
    distance_m: tuple[float, float],
    max_tilt_deg: float,
    max_roll_deg: float,
) -> Board | None:
    """One random board pose whose centre is seen at image angle in ``phi_range`` (rad); None if the drawn
    pixel is not seen."""
    cols, rows = sizes[int(rng.integers(len(sizes)))]
    phi = rng.uniform(*phi_range)
    inner, outer = camera.cutoff_radius, camera.outer_radius
    r = rng.uniform(inner + 0.05 * (outer - inner), outer - 0.05 * (outer - inner))
    uv = np.array([camera.centre[0] + r * math.cos(phi), camera.centre[1] + r * math.sin(phi)])
    origins, directions = camera.trace(uv)
    if not np.all(np.isfinite(directions)):
        return None
    d = directions / np.linalg.norm(directions)
    centre = origins + rng.uniform(*distance_m) * d
    k = _magnification(camera, centre, d)
    if not (math.isfinite(k) and k > 0):
        return None
    # The board's longer side, margin included, spans a drawn fraction of the annulus's width.
    extent = rng.uniform(*span) * (outer - inner) / k
    if extent > _MAX_EXTENT_RAD:
        return None
    distance = float(np.linalg.norm(centre - origins))
    square = 2.0 * distance * math.tan(0.5 * extent) / (max(cols, rows) + 3)
    # Facing the camera within max_tilt_deg: the board's z (away from the camera) is the ray turned off it.
    e1, e2 = _perpendicular(d)
    about = rng.uniform(0.0, 2.0 * math.pi)
    z = _turn(d, math.cos(about) * e1 + math.sin(about) * e2, math.radians(rng.uniform(0.0, max_tilt_deg)))
    # Held upright: y (down the columns) as close to the world's down as the facing allows, then rolled.
    down = np.array([0.0, 0.0, -1.0]) - z * (-z[2])
    if np.linalg.norm(down) < 0.2:
        down = _perpendicular(z)[0]
    y = down / np.linalg.norm(down)
    y = _turn(y, z, math.radians(rng.uniform(-max_roll_deg, max_roll_deg)))
    x = np.cross(y, z)
    rotation = np.stack([x, y, z], axis=1)
    offset = rotation[:, :2] @ (0.5 * square * np.array([cols - 1, rows - 1]))
    return Board(cols=cols, rows=rows, square=square, rotation=rotation, translation=centre - offset)


def board_poses(
    camera: SimulatedCamera,
    count: int,
    seed: int,
    *,
    sizes: tuple[tuple[int, int], ...] = BOARD_SIZES,
    span: tuple[float, float] = (0.4, 1.6),
    distance_m: tuple[float, float] = (0.5, 1.5),
    max_tilt_deg: float = 40.0,
    max_roll_deg: float = 35.0,
    margin_px: float = 4.0,
    min_square_px: float = 8.0,
    attempts: int = 2000,
) -> tuple[Board, ...]:
    """Poses of ``count`` checkerboards a person holds around the camera, every corner in view.

    The boards spread over azimuth (board ``k`` is seen in the ``k``-th of ``count`` equal sectors of
    image angle, from a random start) and over the visible elevation band (the pixel radius of a board's
    centre is drawn uniformly between the cut-off disc and the image circle, 5% of the annulus's width
    clear of each). Each board: inner-corner counts drawn from ``sizes``; its centre ``distance_m`` m along
    that pixel's ray; its square so that the board, margin included, spans a fraction ``span`` of the
    annulus's width (pixels, at the local magnification; at most 100 deg seen from O_m). The default
    reaches boards as big as on real checkerboard sets, whose boards span 1.2-2 times the radial spread
    of all their corners (``span=(1.0, 1.6)`` gives 1.15-1.44 here, the default about 0.6). After every
    tenth of the ``attempts`` without a pose, the span is taken 0.8 times smaller: a crowded view gets
    smaller boards. Its face within ``max_tilt_deg`` of facing the camera (the angle between its normal
    and the ray to its centre, uniform); held upright (its y axis toward the world's down), rolled by up
    to ``max_roll_deg``. A draw is kept when every corner of the checker (the inner corners and the
    outer corners of the outermost squares) projects ``margin_px`` inside the frame and the annulus,
    neighbouring inner corners are at least ``min_square_px`` apart, the board with its margin stays
    5 cm inside the line scenes' room, and its image (with its margin) keeps clear of the boards before
    it (so no board hides another).

    Parameters
    ----------
    camera : SimulatedCamera
        The camera (any: rays from ``camera.trace``, pixels from ``camera.project``).
    count : int
        Boards, >= 1.
    seed : int
        Seeds every draw.

    Returns
    -------
    tuple of Board

    Raises
    ------
    PanomapError
        If a board finds no pose within ``attempts`` draws.
    """
    if count < 1:
        raise PanomapError(f"count must be >= 1, got {count}")
    rng = np.random.default_rng(seed)
    start = rng.uniform(0.0, 2.0 * math.pi)
    sector = 2.0 * math.pi / count
    boards: list[Board] = []
    footprints: list[tuple[NDArray[np.float64], float]] = []
    for k in range(count):
        phi_range = (start + k * sector, start + (k + 1) * sector)
        for attempt in range(attempts):
            # Where big boards do not fit (a crowded view), ever smaller ones: 0.8 times every tenth of the draws.
            shrink = 0.8 ** (10 * attempt // attempts)
            scaled = (span[0] * shrink, span[1] * shrink)
            board = _pose_candidate(camera, rng, phi_range, sizes, scaled, distance_m, max_tilt_deg, max_roll_deg)
            if board is None or not _in_room(board.outline()):
                continue
            checker = board.points(
                np.stack(np.meshgrid(np.arange(-1, board.cols + 1), np.arange(-1, board.rows + 1)), axis=-1)
                .reshape(-1, 2)
                .astype(np.float64)
                * board.square
            )
            if not np.all(_shown(camera, camera.project(checker), margin_px)):
                continue
            px = camera.project(board.corners).reshape(board.rows, board.cols, 2)
            spacing = min(
                float(np.min(np.hypot(*np.moveaxis(np.diff(px, axis=1), -1, 0)))),
                float(np.min(np.hypot(*np.moveaxis(np.diff(px, axis=0), -1, 0)))),
            )
            if spacing < min_square_px:
                continue
            middle, radius = _footprint(camera, board)
            if any(np.hypot(*(middle - m)) < radius + rad for m, rad in footprints):
                continue
            boards.append(board)
            footprints.append((middle, radius))
            break
        else:
            raise PanomapError(f"found no pose for board {k + 1} of {count} in {attempts} draws (seed {seed})")
    return tuple(boards)


# -- rendering --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Look:
    """How a board prints and is lit: its black and white levels and a linear light gradient across it
    (fraction of the level per board length, along x and y)."""

    black: float
    white: float
    gradient: tuple[float, float]


def _board_grey(board: Board, look: _Look, x: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.float64]:
    """Grey levels (n,) of board-plane points ``(x, y)`` (m) inside the board's margin."""
    a = np.floor(x / board.square)
    b = np.floor(y / board.square)
    checker = (a >= -1) & (a <= board.cols - 1) & (b >= -1) & (b <= board.rows - 1)
    black = checker & ((a + b) % 2 == 0)
    length = board.square * (max(board.cols, board.rows) + 3)
    light = 1.0 + (look.gradient[0] * x + look.gradient[1] * y) / length
    return np.asarray(np.where(black, look.black, look.white) * light)


def _shade(
    camera: SimulatedCamera,
    uv: NDArray[np.float64],
    boards: tuple[Board, ...],
    looks: tuple[_Look, ...],
    background: str,
    seed: int,
) -> NDArray[np.float64]:
    """Grey levels (n,) (before the sensor) seen at sub-pixel points ``uv`` (n, 2): the nearest board along
    each ray, else the room; 0 outside the image circle, the housing inside the cut-off disc."""
    origins, directions = camera.trace(uv)
    ok = np.all(np.isfinite(directions), axis=1)
    grey = np.zeros(len(uv))
    r = np.hypot(uv[:, 0] - camera.centre[0], uv[:, 1] - camera.centre[1])
    grey[(~ok) & (r < camera.cutoff_radius)] = _HOUSING_GREY
    if not ok.any():
        return grey
    o, d = origins[ok], directions[ok]
    seen = room_grey(d, background, seed)
    nearest = np.full(len(d), np.inf)
    for board, look in zip(boards, looks, strict=True):
        normal = board.rotation[:, 2]
        facing = d @ normal
        with np.errstate(divide="ignore", invalid="ignore"):
            along = ((board.translation - o) @ normal) / facing
        local = (o + along[:, None] * d - board.translation) @ board.rotation[:, :2]
        x, y = local[:, 0], local[:, 1]
        s = board.square
        hit = (
            (along > 0)
            & (along < nearest)
            & (x >= -2 * s)
            & (x <= (board.cols + 1) * s)
            & (y >= -2 * s)
            & (y <= (board.rows + 1) * s)
        )
        if not hit.any():
            continue
        level = np.where(facing[hit] > 0, _board_grey(board, look, x[hit], y[hit]), _BACK_GREY)
        seen[hit] = level
        nearest[hit] = along[hit]
    grey[ok] = seen
    return grey


def _shade_chunked(
    camera: SimulatedCamera,
    uv: NDArray[np.float64],
    boards: tuple[Board, ...],
    looks: tuple[_Look, ...],
    background: str,
    seed: int,
) -> NDArray[np.float64]:
    """:func:`_shade` over ``uv`` (n, 2) in chunks of ``_SAMPLES_PER_CHUNK``."""
    out = np.empty(len(uv))
    for start in range(0, len(uv), _SAMPLES_PER_CHUNK):
        stop = start + _SAMPLES_PER_CHUNK
        out[start:stop] = _shade(camera, uv[start:stop], boards, looks, background, seed)
    return out


def _render(
    camera: SimulatedCamera,
    boards: tuple[Board, ...],
    looks: tuple[_Look, ...],
    background: str,
    seed: int,
    supersample: int,
) -> NDArray[np.float64]:
    """(H, W) grey levels, each pixel the mean over its area: one ray at every pixel's centre, then
    ``supersample**2`` rays at the sub-pixel centres of every pixel whose 3 x 3 neighbourhood spans more
    than ``_EDGE_LEVELS`` grey levels (an edge crossing a pixel separates the centres of some pair of
    pixels in that neighbourhood)."""
    width, height = camera.image_size
    v, u = np.mgrid[0:height, 0:width].astype(np.float64)
    centres = np.stack([u.ravel(), v.ravel()], axis=1)
    grey = _shade_chunked(camera, centres, boards, looks, background, seed).reshape(height, width)
    if supersample <= 1:
        return grey
    kernel = np.ones((3, 3), np.uint8)
    g32 = grey.astype(np.float32)
    edge = (cv2.dilate(g32, kernel) - cv2.erode(g32, kernel)) > _EDGE_LEVELS
    rows, cols = np.nonzero(edge)
    sub = (np.arange(supersample) + 0.5) / supersample - 0.5
    du, dv = np.meshgrid(sub, sub)
    offsets = np.stack([du.ravel(), dv.ravel()], axis=1)
    samples = (np.stack([cols, rows], axis=1)[:, None, :] + offsets[None, :, :]).reshape(-1, 2)
    fine = _shade_chunked(camera, samples.astype(np.float64), boards, looks, background, seed)
    grey[rows, cols] = fine.reshape(len(rows), -1).mean(axis=1)
    return grey


def render_board_scene(
    camera: SimulatedCamera,
    boards: tuple[Board, ...],
    seed: int = 0,
    supersample: int = 3,
    *,
    background: str = "lines",
    noise: float = 2.5,
    jpeg_quality: int = 85,
    falloff: float = 0.45,
    blur_px: float = 0.0,
) -> BoardScene:
    """Render checkerboards in the line scenes' room through ``camera``, degrade the image as a sensor
    does, and give the true pixels of every board's inner corners.

    Each pixel is the mean grey level over its area (``supersample**2`` rays where anything changes
    within it, one ray elsewhere); each ray meets the nearest board (black squares 20-45, white 195-235
    grey levels, lit with a gradient of up to 12% across the board, all drawn per board; a board's back
    is plain grey) or else the room. Then a lens's blur (``blur_px``, none by default) and, as the line
    scenes: vignetting (``falloff`` at the rim, 0.1 more on one side), Gaussian sensor noise of
    ``noise`` grey levels and JPEG at ``jpeg_quality``.

    Parameters
    ----------
    camera : SimulatedCamera
        The true camera (e.g. :func:`panomap.simulate.line_scenes.line_camera`), at O_m.
    boards : tuple of Board
        The boards (e.g. :func:`board_poses`), in the camera frame.
    seed : int
        Seeds the boards' looks, the room's texture, the vignetting's dim side and the noise.
    supersample : int
        Rays per pixel along each axis where the image changes, >= 1.
    background : {'lines', 'dark'}
        The room (:data:`panomap.simulate.line_scenes.SCENE_KINDS`): its painted lines, or dim and bare.
    noise : float
        Sensor noise (grey levels, Gaussian) before the JPEG.
    jpeg_quality : int
        JPEG quality, 1..100.
    falloff : float
        Vignetting at the rim (fraction of the light lost), plus 0.1 more on one side.
    blur_px : float
        A lens out of focus: the render blurred by a Gaussian of this sigma (px) before the sensor
        (part of :attr:`BoardScene.clean`); 0 (default): as sharp as the pixels.

    Returns
    -------
    BoardScene
    """
    if background not in SCENE_KINDS:
        raise PanomapError(f"background must be one of {SCENE_KINDS}, got {background!r}")
    if supersample < 1:
        raise PanomapError(f"supersample must be >= 1, got {supersample}")
    if not (math.isfinite(blur_px) and blur_px >= 0):
        raise PanomapError(f"blur_px must be finite and >= 0, got {blur_px}")
    rng = np.random.default_rng(seed)
    looks = tuple(
        _Look(
            black=float(rng.uniform(20.0, 45.0)),
            white=float(rng.uniform(195.0, 235.0)),
            gradient=(float(rng.uniform(-0.12, 0.12)), float(rng.uniform(-0.12, 0.12))),
        )
        for _ in boards
    )
    grey = _render(camera, boards, looks, background, seed, supersample)
    if blur_px > 0:
        grey = np.asarray(cv2.GaussianBlur(grey, (0, 0), blur_px), dtype=np.float64)
    clean = np.clip(np.rint(grey), 0, 255).astype(np.uint8)
    dim_angle = float(rng.uniform(0, 2 * math.pi))
    image = vignette(clean, camera.centre, float(camera.outer_radius), falloff=falloff, dim=0.1, dim_angle=dim_angle)
    image = noisy_jpeg(image, rng, noise=noise, quality=jpeg_quality)
    truth = tuple(
        BoardTruth(pixels=camera.project(board.corners), grid=board.grid, points=board.corners) for board in boards
    )
    return BoardScene(image=image, clean=clean, camera=camera, boards=tuple(boards), truth=truth)
