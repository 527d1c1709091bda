"""Rendered scenes for learning a camera from straight lines, with their true lines and curves.

A box-shaped room seen from inside by an omni-camera at O_m (the world origin, z up): painted
straight edges (the room's own edges, floor tiles in a checker, a door, a window with its bars,
shelves, a skirting board) and curved things that are no lines (a round rug, a ring on the floor, a
clock, a painted disc, a round mirror). Every boundary is known in closed form, so the tests and
the bench know each straight world line (:class:`WorldLine`), its true image (the pixels of its
visible points through the true camera) and the images of the curved things.

Kinds of scene: ``'lines'`` (the above) and ``'dark'`` (a dim, featureless room: too few lines).
Cameras (:func:`line_camera`): ``'fisheye190'`` (a 190 deg equidistant fisheye on a 16:9 sensor, the
image circle cut by the frame's top and bottom) and ``'hyperbolic'`` (a hyperbolic mirror, unified
``xi = 0.8``, on a 4:3 sensor, with the camera's own reflection as a cut-off disc); either tilted.

Convention: world axes x, y horizontal, z up, metres, relative to O_m; pixel (u, v), u the column,
v the row, the centre of the top-left pixel at (0, 0); images (H, W, 3) uint8 BGR.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from ..errors import PanomapError
from .cameras import RadialCamera, SimulatedCamera, TiltedCamera, mount_rotation
from .degrade import noisy_jpeg, vignette

#: The room's walls (x, y) and floor and ceiling heights (z), m, relative to O_m.
ROOM_X = (-2.6, 3.1)
ROOM_Y = (-2.2, 2.4)
ROOM_Z = (-1.3, 1.5)
#: Side of a floor tile (m).
TILE_M = 0.5
#: Grey levels either side of a visible boundary at least this far apart count as an edge.
_VISIBLE_STEP = 12.0
#: Scene kinds.
SCENE_KINDS = ("lines", "dark")
#: Camera kinds.
CAMERA_KINDS = ("fisheye190", "hyperbolic")

_PLANES = (  # (axis, value, name)
    (0, ROOM_X[0], "wall x-"),
    (0, ROOM_X[1], "wall x+"),
    (1, ROOM_Y[0], "wall y-"),
    (1, ROOM_Y[1], "wall y+"),
    (2, ROOM_Z[0], "floor"),
    (2, ROOM_Z[1], "ceiling"),
)


@dataclass(frozen=True)
class WorldLine:
    """A straight world segment from ``start`` to ``end`` (3,), m, relative to O_m; ``name`` says what it is."""

    name: str
    start: tuple[float, float, float]
    end: tuple[float, float, float]


@dataclass(frozen=True)
class WorldCircle:
    """A painted circle (the boundary of a disc) of ``radius`` m about ``centre`` (3,) in the plane with unit
    ``normal`` (3,): a curved thing that is no line."""

    name: str
    centre: tuple[float, float, float]
    normal: tuple[float, float, float]
    radius: float


@dataclass(frozen=True)
class LineScene:
    """A rendered scene and its truth.

    Attributes
    ----------
    image : (H, W, 3) uint8
        The omni-image as the sensor delivers it (vignetting, noise, JPEG).
    clean : (H, W, 3) uint8
        The same before vignetting, noise and JPEG.
    camera : SimulatedCamera
        The true camera (tilted).
    lines : tuple of WorldLine
        Every straight boundary of the scene.
    line_pixels : tuple of (n, 2) float64
        Per line, the true pixels [u, v] of its visible points (an edge shows there, inside the image
        circle and the frame, outside the cut-off disc), ordered along the line, spaced <= 0.5 px
        within a visible stretch; empty (0, 2) where none shows.
    curves : tuple of WorldCircle
        The curved things.
    curve_pixels : tuple of (n, 2) float64
        Their true pixels, as ``line_pixels``.
    """

    image: NDArray[np.uint8]
    clean: NDArray[np.uint8]
    camera: SimulatedCamera
    lines: tuple[WorldLine, ...]
    line_pixels: tuple[NDArray[np.float64], ...]
    curves: tuple[WorldCircle, ...] = field(default=())
    curve_pixels: tuple[NDArray[np.float64], ...] = field(default=())


def line_camera(
    kind: str,
    scale: float = 1.0,
    *,
    tilt_deg: float = 2.0,
    toward_deg: float = 30.0,
    centre_offset: tuple[float, float] = (3.3, -2.1),
    phi0: float = 0.4,
    s: int = 1,
) -> TiltedCamera:
    """A camera for line scenes, looking down, tilted by ``tilt_deg`` toward world azimuth ``toward_deg``.

    - ``'fisheye190'``: equidistant, ``alpha_max = 95 deg``, on a ``1920 x 1080`` sensor (times
      ``scale``), image circle radius ``640*scale`` px: the frame cuts its top and bottom.
    - ``'hyperbolic'``: unified law ``xi = 0.8``, ``alpha`` in [12, 100] deg, on ``1600 x 1200``
      (times ``scale``), image circle radius ``0.47*1200*scale`` px.

    ``centre_offset`` (px, times ``scale``) moves the centre off the frame's middle.
    """
    deg = math.pi / 180.0
    if kind == "fisheye190":
        width, height = round(1920 * scale), round(1080 * scale)
        outer = 640.0 * scale
        law, xi, a_min, a_max = "equidistant", 0.0, 0.0, 95 * deg
        lens_scale = outer / a_max
    elif kind == "hyperbolic":
        width, height = round(1600 * scale), round(1200 * scale)
        outer = 0.47 * 1200 * scale
        law, xi, a_min, a_max = "unified", 0.8, 12 * deg, 100 * deg
        lens_scale = outer * (xi + math.cos(a_max)) / math.sin(a_max)
    else:
        raise PanomapError(f"camera kind must be one of {CAMERA_KINDS}, got {kind!r}")
    centre = ((width - 1) / 2.0 + centre_offset[0] * scale, (height - 1) / 2.0 + centre_offset[1] * scale)
    inner = RadialCamera(
        name=kind,
        law=law,
        scale=lens_scale,
        xi=xi,
        image_size=(width, height),
        centre=centre,
        s=s,
        phi0=phi0,
        alpha_min=a_min,
        alpha_max=a_max,
    )
    return TiltedCamera(camera=inner, rotation=mount_rotation(tilt_deg * deg, toward_deg * deg))


# -- the scene ----------------------------------------------------------------------------------


def _scene_lines() -> list[WorldLine]:
    """Every straight boundary of the ``'lines'`` scene."""
    (x0, x1), (y0, y1), (z0, z1) = ROOM_X, ROOM_Y, ROOM_Z
    out: list[WorldLine] = []
    corners = [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]
    for i, (a, b) in enumerate(zip(corners, corners[1:] + corners[:1], strict=True)):
        out.append(WorldLine(f"floor edge {i}", (a[0], a[1], z0), (b[0], b[1], z0)))
        out.append(WorldLine(f"ceiling edge {i}", (a[0], a[1], z1), (b[0], b[1], z1)))
        out.append(WorldLine(f"corner {i}", (a[0], a[1], z0), (a[0], a[1], z1)))
        skirting = z0 + 0.12
        out.append(WorldLine(f"skirting {i}", (a[0], a[1], skirting), (b[0], b[1], skirting)))
    for k in range(math.ceil(x0 / TILE_M), math.floor(x1 / TILE_M) + 1):
        x = k * TILE_M
        if x0 < x < x1:
            out.append(WorldLine(f"tile x={x:.1f}", (x, y0, z0), (x, y1, z0)))
    for k in range(math.ceil(y0 / TILE_M), math.floor(y1 / TILE_M) + 1):
        y = k * TILE_M
        if y0 < y < y1:
            out.append(WorldLine(f"tile y={y:.1f}", (x0, y, z0), (x1, y, z0)))
    # the door on wall x+: y in [-0.5, 0.4], up to z = 0.8
    out += [
        WorldLine("door left", (x1, -0.5, z0), (x1, -0.5, 0.8)),
        WorldLine("door right", (x1, 0.4, z0), (x1, 0.4, 0.8)),
        WorldLine("door top", (x1, -0.5, 0.8), (x1, 0.4, 0.8)),
    ]
    # the window on wall y+: x in [-1.2, 0.6], z in [-0.3, 0.9], bars at x = -0.3 and z = 0.3 (5 cm wide)
    wx0, wx1, wz0, wz1 = -1.2, 0.6, -0.3, 0.9
    out += [
        WorldLine("window left", (wx0, y1, wz0), (wx0, y1, wz1)),
        WorldLine("window right", (wx1, y1, wz0), (wx1, y1, wz1)),
        WorldLine("window bottom", (wx0, y1, wz0), (wx1, y1, wz0)),
        WorldLine("window top", (wx0, y1, wz1), (wx1, y1, wz1)),
    ]
    for e in (-0.325, -0.275):
        out.append(WorldLine(f"window bar x={e}", (e, y1, wz0), (e, y1, wz1)))
    for e in (0.275, 0.325):
        out.append(WorldLine(f"window bar z={e}", (wx0, y1, e), (wx1, y1, e)))
    # shelves on wall x-: y in [-1.5, 0.5], boards 3 cm thick with their tops at z
    for z in (-0.6, -0.2, 0.2):
        out.append(WorldLine(f"shelf top z={z}", (x0, -1.5, z), (x0, 0.5, z)))
        out.append(WorldLine(f"shelf bottom z={z}", (x0, -1.5, z - 0.03), (x0, 0.5, z - 0.03)))
    return out


def _scene_curves() -> list[WorldCircle]:
    """The curved things of the ``'lines'`` scene."""
    (x0, x1), y0, z0 = ROOM_X, ROOM_Y[0], ROOM_Z[0]
    return [
        WorldCircle("rug", (1.3, -1.0, z0), (0.0, 0.0, 1.0), 0.45),
        WorldCircle("ring outer", (-1.4, 1.3, z0), (0.0, 0.0, 1.0), 0.40),
        WorldCircle("ring inner", (-1.4, 1.3, z0), (0.0, 0.0, 1.0), 0.30),
        WorldCircle("clock", (0.9, y0, 0.25), (0.0, 1.0, 0.0), 0.25),
        WorldCircle("disc", (x1, 1.4, -0.4), (1.0, 0.0, 0.0), 0.35),
        WorldCircle("round mirror", (x0, 1.5, 0.1), (1.0, 0.0, 0.0), 0.3),
    ]


def _texture(p: NDArray[np.float64], seed: int) -> NDArray[np.float64]:
    """A smooth random texture (grey levels, about +-5) of world points (n, 3): a sum of plane waves."""
    rng = np.random.default_rng(seed)
    out = np.zeros(len(p))
    for _ in range(6):
        k = rng.normal(size=3)
        k *= rng.uniform(4.0, 40.0) / np.linalg.norm(k)
        out += 2.0 * np.sin(p @ k + rng.uniform(0, 2 * math.pi))
    return out


def _in_disc(p: NDArray[np.float64], c: WorldCircle) -> NDArray[np.bool_]:
    """Which points (n, 3) on the circle's plane lie inside its disc."""
    return np.asarray(np.linalg.norm(p - np.asarray(c.centre), axis=1) < c.radius)


def surface_grey(
    points: NDArray[np.float64], surface: NDArray[np.int64], kind: str = "lines", seed: int = 0
) -> NDArray[np.float64]:
    """Grey level (before the sensor) of points (n, 3) on the room's surfaces (indices into the six planes:
    walls x-, x+, y-, y+, floor, ceiling)."""
    x, y, z = points[:, 0], points[:, 1], points[:, 2]
    texture = _texture(points, seed)
    if kind == "dark":
        return 22.0 + 0.4 * texture
    base = np.array([185.0, 200.0, 165.0, 210.0, 0.0, 225.0])[surface]
    floor = surface == 4
    parity = (np.floor(x / TILE_M) + np.floor(y / TILE_M)) % 2
    g = np.where(floor, np.where(parity == 0, 150.0, 105.0), base)
    walls = surface <= 3
    g = np.where(walls & (z < ROOM_Z[0] + 0.12), 80.0, g)
    door = (surface == 1) & (y > -0.5) & (y < 0.4) & (z < 0.8)
    g = np.where(door, 70.0, g)
    window = (surface == 3) & (x > -1.2) & (x < 0.6) & (z > -0.3) & (z < 0.9)
    bars = window & ((np.abs(x + 0.3) < 0.025) | (np.abs(z - 0.3) < 0.025))
    g = np.where(window, np.where(bars, 60.0, 245.0), g)
    shelf = (surface == 0) & (y > -1.5) & (y < 0.5)
    for top in (-0.6, -0.2, 0.2):
        g = np.where(shelf & (z < top) & (z > top - 0.03), 55.0, g)
    c = {w.name: w for w in _scene_curves()}
    g = np.where(floor & _in_disc(points, c["rug"]), 50.0, g)
    ring = floor & _in_disc(points, c["ring outer"]) & ~_in_disc(points, c["ring inner"])
    g = np.where(ring, 235.0, g)
    g = np.where((surface == 2) & _in_disc(points, c["clock"]), 40.0, g)
    g = np.where((surface == 1) & _in_disc(points, c["disc"]), 110.0, g)
    g = np.where((surface == 0) & _in_disc(points, c["round mirror"]), 235.0, g)
    return np.asarray(g + texture)


def _hit(directions: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Where rays (n, 3) from O_m meet the room (points (n, 3)) and which surface (n,)."""
    t_best = np.full(len(directions), np.inf)
    surface = np.zeros(len(directions), dtype=np.int64)
    with np.errstate(divide="ignore", invalid="ignore"):
        for i, (axis, value, _) in enumerate(_PLANES):
            t = value / directions[:, axis]
            better = (t > 0) & (t < t_best)
            t_best = np.where(better, t, t_best)
            surface = np.where(better, i, surface)
    return directions * t_best[:, None], surface


def room_grey(directions: NDArray[np.float64], kind: str = "lines", seed: int = 0) -> NDArray[np.float64]:
    """Grey levels (n,) (before the sensor) of the room where rays (n, 3) from O_m, world axes, meet it."""
    p, surface = _hit(directions)
    return surface_grey(p, surface, kind, seed)


def render_grey(
    camera: SimulatedCamera, kind: str = "lines", supersample: int = 3, seed: int = 0
) -> NDArray[np.float64]:
    """(H, W) grey levels of the scene through ``camera``: each pixel the mean of ``supersample**2`` rays at
    its sub-pixel centres; 0 outside the image circle, a dark housing (25) inside the cut-off disc."""
    width, height = camera.image_size
    sub = (np.arange(supersample) + 0.5) / supersample - 0.5
    out = np.zeros((height, width))
    rows = max(1, 400_000 // (width * supersample * supersample))
    u = np.arange(width, dtype=np.float64)
    centre = np.asarray(camera.centre)
    for v_start in range(0, height, rows):
        v = np.arange(v_start, min(height, v_start + rows), dtype=np.float64)
        uu = (u[None, :, None, None] + sub[None, None, None, :]) + 0 * v[:, None, None, None]
        vv = (v[:, None, None, None] + sub[None, None, :, None]) + 0 * u[None, :, None, None]
        uv = np.stack(np.broadcast_arrays(uu, vv), axis=-1).reshape(-1, 2)
        _, d = camera.trace(uv)
        ok = np.all(np.isfinite(d), axis=1)
        grey = np.zeros(len(uv))
        if ok.any():
            grey[ok] = room_grey(d[ok], kind, seed)
        r = np.hypot(uv[:, 0] - centre[0], uv[:, 1] - centre[1])
        grey[(~ok) & (r < camera.cutoff_radius)] = 25.0
        out[v_start : v_start + len(v)] = grey.reshape(len(v), width, supersample * supersample).mean(axis=2)
    return out


def _visible_pixels(
    camera: SimulatedCamera,
    points: NDArray[np.float64],
    across: NDArray[np.float64],
    surface: int,
    kind: str,
    margin_px: float,
) -> NDArray[np.float64]:
    """Pixels (m, 2) of those ``points`` (n, 3) along a boundary where the grey level steps across it
    (``across`` (n, 3): unit vectors in the surface, across the boundary) and the image shows them."""
    eps = 0.004
    surf = np.full(len(points), surface, dtype=np.int64)
    step = np.abs(surface_grey(points + eps * across, surf, kind) - surface_grey(points - eps * across, surf, kind))
    px = camera.project(points)
    ok = np.all(np.isfinite(px), axis=1) & (step > _VISIBLE_STEP)
    return np.asarray(px[ok & _shown(camera, px, margin_px)], dtype=np.float64)


def _shown(camera: SimulatedCamera, px: NDArray[np.float64], margin_px: float) -> NDArray[np.bool_]:
    """Which pixels (n, 2) lie ``margin_px`` inside the annulus between the cut-off disc and the image
    circle and inside the frame (NaN: not shown)."""
    r = np.hypot(px[:, 0] - camera.centre[0], px[:, 1] - camera.centre[1])
    w, h = camera.image_size
    with np.errstate(invalid="ignore"):
        ok = (r > camera.cutoff_radius + margin_px) & (r < camera.outer_radius - margin_px)
        ok &= (px[:, 0] > margin_px) & (px[:, 0] < w - 1 - margin_px)
        ok &= (px[:, 1] > margin_px) & (px[:, 1] < h - 1 - margin_px)
    return np.asarray(ok)


def _surface_of(p: NDArray[np.float64]) -> int:
    """The plane (index into the six) a point on the room's surface lies on; for an edge of two, the first."""
    for i, (axis, value, _) in enumerate(_PLANES):
        if abs(p[axis] - value) < 1e-9:
            return i
    raise PanomapError(f"{p} is on no surface of the room")


def _samples(length_m: float) -> int:
    """Points along a boundary of ``length_m``: every 1.5 mm (under 0.5 px in every scene here)."""
    return max(2, math.ceil(length_m / 0.0015) + 1)


def line_truth(camera: SimulatedCamera, line: WorldLine, kind: str, margin_px: float = 2.0) -> NDArray[np.float64]:
    """True pixels (m, 2) of the visible points of ``line``, ordered from its start to its end."""
    a, b = np.asarray(line.start), np.asarray(line.end)
    t = np.linspace(0.0, 1.0, _samples(float(np.linalg.norm(b - a))))
    pts = a + t[:, None] * (b - a)
    direction = (b - a) / np.linalg.norm(b - a)
    surface = _surface_of(0.5 * (a + b))
    normal = np.zeros(3)
    normal[_PLANES[surface][0]] = 1.0
    across = np.cross(normal, direction)
    # a room edge: the step is between two planes; test on the plane beside it instead
    on_edge = sum(abs(0.5 * (a + b)[ax] - val) < 1e-9 for ax, val, _ in _PLANES) > 1
    if on_edge:
        return _edge_pixels(camera, pts, kind, margin_px)
    return _visible_pixels(camera, pts, np.broadcast_to(across, pts.shape), surface, kind, margin_px)


def _edge_pixels(camera: SimulatedCamera, pts: NDArray[np.float64], kind: str, margin_px: float) -> NDArray[np.float64]:
    """Pixels of points on an edge of the room, where the two planes' grey levels differ next to it."""
    mid = pts[len(pts) // 2]
    planes = [i for i, (ax, val, _) in enumerate(_PLANES) if abs(mid[ax] - val) < 1e-9]
    inward = np.zeros((2, 3))
    for k in range(2):
        other = _PLANES[planes[1 - k]]
        inward[k, other[0]] = -np.sign(other[1])  # step off the other plane, into the room along this one
    eps = 0.004
    g = [surface_grey(pts + eps * inward[k], np.full(len(pts), planes[k], dtype=np.int64), kind) for k in range(2)]
    step = np.abs(g[0] - g[1])
    px = camera.project(pts)
    ok = np.all(np.isfinite(px), axis=1) & (step > _VISIBLE_STEP)
    return np.asarray(px[ok & _shown(camera, px, margin_px)], dtype=np.float64)


def curve_truth(camera: SimulatedCamera, curve: WorldCircle, kind: str, margin_px: float = 2.0) -> NDArray[np.float64]:
    """True pixels (m, 2) of the visible points of a painted circle, in order round it."""
    n = np.asarray(curve.normal, dtype=np.float64)
    e1 = np.cross(n, [0.0, 0.0, 1.0] if abs(n[2]) < 0.9 else [1.0, 0.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    t = np.linspace(0.0, 2 * math.pi, _samples(2 * math.pi * curve.radius))
    radial = np.cos(t)[:, None] * e1 + np.sin(t)[:, None] * e2
    pts = np.asarray(curve.centre) + curve.radius * radial
    surface = _surface_of(np.asarray(curve.centre))
    return _visible_pixels(camera, pts, radial, surface, kind, margin_px)


def render_line_scene(
    camera: SimulatedCamera,
    kind: str = "lines",
    *,
    seed: int = 0,
    supersample: int = 3,
    noise: float = 2.5,
    jpeg_quality: int = 85,
    falloff: float = 0.45,
) -> LineScene:
    """Render a scene through ``camera`` and degrade it as a sensor does; with its truth.

    Parameters
    ----------
    camera : SimulatedCamera
        The true camera (e.g. :func:`line_camera`), at O_m.
    kind : {'lines', 'dark'}
        The scene.
    seed : int
        Seeds the texture, the sensor noise and the vignetting's dim side.
    supersample : int
        Rays per pixel along each axis.
    noise : float
        Sensor noise (grey levels, Gaussian) before the JPEG.
    jpeg_quality : int
        JPEG quality, 1..100.
    falloff : float
        Vignetting at the rim (fraction of the light lost), plus 0.1 more on one side.
    """
    if kind not in SCENE_KINDS:
        raise PanomapError(f"scene kind must be one of {SCENE_KINDS}, got {kind!r}")
    rng = np.random.default_rng(seed)
    grey = render_grey(camera, kind, supersample, seed)
    tint = np.array([0.92, 1.0, 1.06])
    clean = np.clip(np.rint(grey[..., None] * tint), 0, 255).astype(np.uint8)
    dim_angle = float(rng.uniform(0, 2 * math.pi))
    image = vignette(clean, camera.centre, float(camera.outer_radius), falloff=falloff, dim=0.1, dim_angle=dim_angle)
    image = noisy_jpeg(image, rng, noise=noise, quality=jpeg_quality)
    lines = tuple(_scene_lines())
    curves = tuple(_scene_curves())
    line_pixels = tuple(line_truth(camera, line, kind) for line in lines)
    curve_pixels = tuple(curve_truth(camera, c, kind) for c in curves)
    return LineScene(
        image=image,
        clean=clean,
        camera=camera,
        lines=lines,
        line_pixels=line_pixels,
        curves=curves,
        curve_pixels=curve_pixels,
    )
