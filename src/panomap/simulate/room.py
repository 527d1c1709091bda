"""A textured box room, rendered through any simulated omni-camera.

Convention (see ``docs/conventions.md``):

- World frame: origin at a floor corner, ``x`` in ``[0, width]`` along the south wall,
  ``y`` in ``[0, depth]`` along the west wall, ``z`` in ``[0, height]`` up (metres). The
  north wall is at ``y = depth``, the east wall at ``x = width``, the south wall at
  ``y = 0``, the west wall at ``x = 0``.
- Wall coordinates ``(a, z)``: ``a`` (m) runs along a wall from left to right as seen
  from inside the room facing it, ``z`` is the height.
- Pixels ``(u, v)``: u the column, v the row, centre of the top-left pixel at ``(0, 0)``.
  Images are ``(H, W, 3)`` uint8 BGR.
- The camera's nominal position O_m is ``Room.camera``; simulated cameras work relative
  to it.

Textures are procedural and deterministic: a checkerboard floor with grid lines, four
walls of different colours with a skirting line, a rail line, door and window frames and a
big label each, and a plain ceiling.
"""

from __future__ import annotations

import functools
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from panomap.errors import PanomapError
from panomap.simulate.cameras import SimulatedCamera

__all__ = ["WALL_NAMES", "Opening", "Room", "Wall", "load_room", "render", "render_rays"]

#: Wall names, in the order of :attr:`Room.walls`.
WALL_NAMES = ("N", "E", "S", "W")

#: Version of the room JSON format read by :meth:`Room.from_dict`.
ROOM_FORMAT_VERSION = 1

#: Rays traced per chunk by :func:`render` (bounds memory use).
_RAYS_PER_CHUNK = 1 << 18

_LABEL_FONT = cv2.FONT_HERSHEY_SIMPLEX

Colour = tuple[int, int, int]


# ----------------------------------------------------------------------------------------
# Room description
# ----------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Opening:
    """A door or window: a rectangle on a wall, in wall coordinates.

    Parameters
    ----------
    kind : {'door', 'window'}
        What is drawn.
    a : tuple of float
        ``(left, right)`` along the wall (m), seen from inside.
    z : tuple of float
        ``(bottom, top)`` heights (m).
    """

    kind: str
    a: tuple[float, float]
    z: tuple[float, float]


@dataclass(frozen=True)
class Wall:
    """One wall's look.

    Parameters
    ----------
    name : {'N', 'E', 'S', 'W'}
        Which wall.
    colour_bgr : tuple of int
        Base colour.
    label : str
        Text drawn on the wall.
    label_at : tuple of float
        ``(a, z)`` (m) of the label's bottom-left corner.
    label_height : float
        Height (m) of the label's capitals.
    openings : tuple of Opening
        Doors and windows.
    """

    name: str
    colour_bgr: Colour
    label: str
    label_at: tuple[float, float]
    label_height: float
    openings: tuple[Opening, ...]


@dataclass(frozen=True, kw_only=True)
class Room:
    """A box room with a camera mount, textures and landmarks.

    Parameters
    ----------
    width, depth, height : float
        Extent (m) along x, y and z.
    camera : tuple of float
        ``(X0, Y0, Z0)``: the camera's nominal position O_m (m), strictly inside the room.
    tile_size : float
        Side (m) of the floor's checkerboard tiles; tile ``(i, j)`` covers
        ``[i, i+1)*tile_size x [j, j+1)*tile_size`` and has colour
        ``floor_colours_bgr[(i + j) % 2]``.
    grid_line_width : float
        Width (m) of the grid lines along the tile edges.
    skirting_height, rail_height : float
        Heights (m) of the two horizontal lines on every wall.
    feature_line_width : float
        Width (m) of the wall lines and door/window frames (centred on the edges).
    texture_px_per_m : float
        Texture resolution (texels per metre).
    floor_colours_bgr : tuple of two colours
        Checkerboard colours.
    grid_colour_bgr, ceiling_colour_bgr, line_colour_bgr, door_colour_bgr, \
window_colour_bgr : tuple of int
        Colours of the grid lines, ceiling, wall lines and frames, door leaves, window panes.
    walls : tuple of Wall
        The four walls in the order ``('N', 'E', 'S', 'W')``.
    floor_landmarks : tuple of (x, y)
        Tile corners (m) listed as landmarks.
    """

    width: float
    depth: float
    height: float
    camera: tuple[float, float, float]
    tile_size: float
    grid_line_width: float
    skirting_height: float
    rail_height: float
    feature_line_width: float
    texture_px_per_m: float
    floor_colours_bgr: tuple[Colour, Colour]
    grid_colour_bgr: Colour
    ceiling_colour_bgr: Colour
    line_colour_bgr: Colour
    door_colour_bgr: Colour
    window_colour_bgr: Colour
    walls: tuple[Wall, ...]
    floor_landmarks: tuple[tuple[float, float], ...]

    def __post_init__(self) -> None:
        for label in (
            "width",
            "depth",
            "height",
            "tile_size",
            "grid_line_width",
            "feature_line_width",
            "texture_px_per_m",
        ):
            _check_positive(label, getattr(self, label))
        _check_finite("camera", self.camera, 3)
        x0, y0, z0 = self.camera
        if not (0 < x0 < self.width and 0 < y0 < self.depth and 0 < z0 < self.height):
            raise PanomapError(f"camera {self.camera} is not strictly inside the room")
        for label in ("skirting_height", "rail_height"):
            value = getattr(self, label)
            if not (math.isfinite(value) and 0 < value < self.height):
                raise PanomapError(f"{label} must be in (0, height), got {value!r}")
        if len(self.floor_colours_bgr) != 2:
            raise PanomapError("floor_colours_bgr must hold two colours")
        for colour in (
            *self.floor_colours_bgr,
            self.grid_colour_bgr,
            self.ceiling_colour_bgr,
            self.line_colour_bgr,
            self.door_colour_bgr,
            self.window_colour_bgr,
        ):
            _check_colour(colour)
        if tuple(w.name for w in self.walls) != WALL_NAMES:
            raise PanomapError(f"walls must be named {WALL_NAMES} in that order")
        for wall in self.walls:
            self._check_wall(wall)
        for x, y in self.floor_landmarks:
            _check_finite("floor landmark", (x, y), 2)
            if not (0 < x < self.width and 0 < y < self.depth):
                raise PanomapError(f"floor landmark {(x, y)} is not inside the floor")
            for c in (x, y):
                k = round(c / self.tile_size)
                if abs(c - k * self.tile_size) > 1e-9 * self.tile_size:
                    raise PanomapError(f"floor landmark {(x, y)} is not a tile corner")

    def _check_wall(self, wall: Wall) -> None:
        length = self.wall_length(wall.name)
        _check_colour(wall.colour_bgr)
        _check_finite("label_at", wall.label_at, 2)
        _check_positive("label_height", wall.label_height)
        if not wall.label:
            raise PanomapError(f"wall {wall.name}: empty label")
        label_box = self._label_box(wall)
        for opening in wall.openings:
            if opening.kind not in ("door", "window"):
                raise PanomapError(f"wall {wall.name}: unknown opening kind {opening.kind!r}")
            _check_finite("opening a", opening.a, 2)
            _check_finite("opening z", opening.z, 2)
            (a0, a1), (z0, z1) = opening.a, opening.z
            if not (0 < a0 < a1 < length and 0 <= z0 < z1 < self.height):
                raise PanomapError(f"wall {wall.name}: opening {opening} is not inside the wall")
            if _overlap(label_box, (a0, a1, z0, z1)):
                raise PanomapError(f"wall {wall.name}: the label overlaps {opening}")
        la0, la1, lz0, lz1 = label_box
        if not (0 < la0 and la1 < length and 0 < lz0 and lz1 < self.height):
            raise PanomapError(f"wall {wall.name}: the label does not fit on the wall")

    def _label_box(self, wall: Wall) -> tuple[float, float, float, float]:
        """``(a0, a1, z0, z1)`` (m) covered by a wall's label (baseline at ``label_at``)."""
        scale, thickness = self._label_font(wall)
        (w_px, h_px), _ = cv2.getTextSize(wall.label, _LABEL_FONT, scale, thickness)
        a0, z0 = wall.label_at
        return a0, a0 + w_px / self.texture_px_per_m, z0, z0 + h_px / self.texture_px_per_m

    def _label_font(self, wall: Wall) -> tuple[float, int]:
        """cv2 font scale and thickness that draw capitals ``label_height`` tall."""
        (_, h1), _ = cv2.getTextSize("H", _LABEL_FONT, 1.0, 1)
        target = wall.label_height * self.texture_px_per_m
        return target / h1, max(1, round(target / 10))

    # -- geometry ------------------------------------------------------------------------

    def wall(self, name: str) -> Wall:
        """The wall called ``name`` (one of ``'N', 'E', 'S', 'W'``)."""
        return self.walls[WALL_NAMES.index(name)]

    def wall_length(self, name: str) -> float:
        """Length (m) of a wall: ``width`` for N and S, ``depth`` for E and W."""
        if name not in WALL_NAMES:
            raise PanomapError(f"unknown wall {name!r}")
        return self.width if name in ("N", "S") else self.depth

    def wall_to_world(self, name: str, a: ArrayLike, z: ArrayLike) -> NDArray[np.float64]:
        """World points of wall coordinates.

        Parameters
        ----------
        name : {'N', 'E', 'S', 'W'}
            The wall.
        a, z : (...) array_like
            Position along the wall (m, left to right seen from inside) and height (m).

        Returns
        -------
        (..., 3) ndarray
            World points (m).
        """
        aa, zz = np.broadcast_arrays(np.asarray(a, np.float64), np.asarray(z, np.float64))
        if name == "N":
            x, y = aa, np.full_like(aa, self.depth)
        elif name == "S":
            x, y = self.width - aa, np.zeros_like(aa)
        elif name == "E":
            x, y = np.full_like(aa, self.width), self.depth - aa
        elif name == "W":
            x, y = np.zeros_like(aa), aa
        else:
            raise PanomapError(f"unknown wall {name!r}")
        return np.stack([x, y, zz], axis=-1)

    def landmarks(self) -> tuple[list[str], NDArray[np.float64]]:
        """Named, easily identified world points.

        Floor tile corners (``floor_x.._y..``), the room's corners on the floor, at the rail
        line and at the ceiling (``corner_SW_floor`` ...), and the corners of every door and
        window (``E_door_bottom_left`` ..., left/right as seen from inside).

        Returns
        -------
        names : list of str
            K unique names.
        points : (K, 3) ndarray
            World points (m).
        """
        names: list[str] = []
        points: list[tuple[float, float, float]] = []
        for x, y in self.floor_landmarks:
            names.append(f"floor_x{x:.2f}_y{y:.2f}")
            points.append((x, y, 0.0))
        corners = {
            "SW": (0.0, 0.0),
            "SE": (self.width, 0.0),
            "NE": (self.width, self.depth),
            "NW": (0.0, self.depth),
        }
        for level, z in (("floor", 0.0), ("rail", self.rail_height), ("ceiling", self.height)):
            for corner, (x, y) in corners.items():
                names.append(f"corner_{corner}_{level}")
                points.append((x, y, z))
        for wall in self.walls:
            for opening in wall.openings:
                for vertical, z in (("bottom", opening.z[0]), ("top", opening.z[1])):
                    for side, a in (("left", opening.a[0]), ("right", opening.a[1])):
                        names.append(f"{wall.name}_{opening.kind}_{vertical}_{side}")
                        p = self.wall_to_world(wall.name, a, z)
                        points.append((float(p[0]), float(p[1]), float(p[2])))
        if len(set(names)) != len(names):
            raise PanomapError("landmark names are not unique (two openings of one kind?)")
        return names, np.array(points, dtype=np.float64)

    # -- (de)serialisation ---------------------------------------------------------------

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Room:
        """Build a room from its JSON description (see ``panomap/data/room.json``).

        Raises
        ------
        PanomapError
            If the format version, a key or a value is wrong.
        """
        if data.get("format_version") != ROOM_FORMAT_VERSION:
            raise PanomapError(f"room format_version must be {ROOM_FORMAT_VERSION}, got {data.get('format_version')!r}")
        if data.get("units", "m") != "m":
            raise PanomapError(f"room units must be 'm', got {data.get('units')!r}")
        try:
            walls = tuple(
                Wall(
                    name=str(w["name"]),
                    colour_bgr=_colour(w["colour_bgr"]),
                    label=str(w["label"]),
                    label_at=_floats(w["label_at"], 2),
                    label_height=float(w["label_height"]),
                    openings=tuple(
                        Opening(
                            kind=str(o["kind"]),
                            a=_floats(o["a"], 2),
                            z=_floats(o["z"], 2),
                        )
                        for o in w.get("openings", [])
                    ),
                )
                for w in data["walls"]
            )
            floor_colours = tuple(_colour(c) for c in data["floor_colours_bgr"])
            if len(floor_colours) != 2:
                raise PanomapError("floor_colours_bgr must hold two colours")
            return cls(
                width=float(data["width"]),
                depth=float(data["depth"]),
                height=float(data["height"]),
                camera=_floats(data["camera"], 3),
                tile_size=float(data["tile_size"]),
                grid_line_width=float(data["grid_line_width"]),
                skirting_height=float(data["skirting_height"]),
                rail_height=float(data["rail_height"]),
                feature_line_width=float(data["feature_line_width"]),
                texture_px_per_m=float(data["texture_px_per_m"]),
                floor_colours_bgr=(floor_colours[0], floor_colours[1]),
                grid_colour_bgr=_colour(data["grid_colour_bgr"]),
                ceiling_colour_bgr=_colour(data["ceiling_colour_bgr"]),
                line_colour_bgr=_colour(data["line_colour_bgr"]),
                door_colour_bgr=_colour(data["door_colour_bgr"]),
                window_colour_bgr=_colour(data["window_colour_bgr"]),
                walls=walls,
                floor_landmarks=tuple(_floats(p, 2) for p in data["floor_landmarks"]),
            )
        except PanomapError:
            raise
        except KeyError as exc:
            raise PanomapError(f"room description lacks the key {exc.args[0]!r}") from None
        except (TypeError, ValueError) as exc:
            raise PanomapError(f"bad room description: {exc}") from None

    def floor_colour_at(self, x: ArrayLike, y: ArrayLike) -> NDArray[np.uint8]:
        """Checkerboard colour of the tiles containing ``(x, y)`` (ignores grid lines).

        Parameters
        ----------
        x, y : (...) array_like
            Floor positions (m).

        Returns
        -------
        (..., 3) ndarray of uint8
            BGR tile colours.
        """
        i = np.floor(np.asarray(x, np.float64) / self.tile_size).astype(np.int64)
        j = np.floor(np.asarray(y, np.float64) / self.tile_size).astype(np.int64)
        palette = np.array(self.floor_colours_bgr, dtype=np.uint8)
        colours: NDArray[np.uint8] = palette[(i + j) % 2]
        return colours


def _check_positive(label: str, value: float) -> None:
    if not (math.isfinite(value) and value > 0):
        raise PanomapError(f"{label} must be finite and > 0, got {value!r}")


def _check_finite(label: str, values: Sequence[float], n: int) -> None:
    if len(values) != n or not all(math.isfinite(v) for v in values):
        raise PanomapError(f"{label} must be {n} finite numbers, got {values!r}")


def _check_colour(colour: Sequence[int]) -> None:
    if len(colour) != 3 or not all(isinstance(c, int) and 0 <= c <= 255 for c in colour):
        raise PanomapError(f"a colour must be three integers in [0, 255], got {colour!r}")


def _colour(value: Any) -> Colour:
    values = [int(c) for c in value]
    if len(values) != 3 or any(float(c) != v for c, v in zip(value, values, strict=True)):
        raise PanomapError(f"a colour must be three integers, got {value!r}")
    return values[0], values[1], values[2]


def _floats(value: Any, n: int) -> Any:
    values = tuple(float(v) for v in value)
    if len(values) != n:
        raise PanomapError(f"expected {n} numbers, got {value!r}")
    return values


def _overlap(box1: tuple[float, float, float, float], box2: tuple[float, float, float, float]) -> bool:
    """Whether two ``(a0, a1, z0, z1)`` rectangles overlap."""
    return box1[0] < box2[1] and box2[0] < box1[1] and box1[2] < box2[3] and box2[2] < box1[3]


def load_room(path: str | Path | None = None) -> Room:
    """Load a room description.

    Parameters
    ----------
    path : str or Path or None
        A room JSON file; None reads the bundled ``panomap/data/room.json`` (a 6 x 5 x 2.6 m
        room, camera at (3.1, 2.4, 2.45) m).

    Returns
    -------
    Room
        The validated room.

    Raises
    ------
    PanomapError
        If the file cannot be read or describes an invalid room (the message names it).
    """
    if path is None:
        text = (resources.files("panomap") / "data" / "room.json").read_text(encoding="utf-8")
        return Room.from_dict(json.loads(text))
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
        if not isinstance(data, dict):
            raise PanomapError("a room description must be a JSON object")
        return Room.from_dict(data)
    except PanomapError as exc:
        raise PanomapError(exc.detail, source=path) from None
    except (OSError, json.JSONDecodeError) as exc:
        raise PanomapError(f"cannot read the room description: {exc}", source=path) from None


# ----------------------------------------------------------------------------------------
# Procedural textures
# ----------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Texture:
    """A read-only ``(rows, cols, 3)`` uint8 image covering ``extent`` metres.

    Texel ``(row, col)`` has its centre at ``((col + 0.5)*sx, (row + 0.5)*sy)`` metres from
    the texture's top-left corner, ``sx = extent[0]/cols``, ``sy = extent[1]/rows``.
    """

    image: NDArray[np.uint8]
    extent: tuple[float, float]


def _texel_centres(n: int, length: float) -> NDArray[np.float64]:
    """Positions (m) of the centres of ``n`` texels spanning ``length`` metres."""
    return (np.arange(n, dtype=np.float64) + 0.5) * (length / n)


def _floor_texture(room: Room) -> _Texture:
    """Checkerboard with grid lines; texture row = y, column = x."""
    cols = max(2, round(room.width * room.texture_px_per_m))
    rows = max(2, round(room.depth * room.texture_px_per_m))
    x = _texel_centres(cols, room.width)
    y = _texel_centres(rows, room.depth)
    parity = (np.floor(y / room.tile_size)[:, None] + np.floor(x / room.tile_size)[None, :]) % 2
    image = np.array(room.floor_colours_bgr, dtype=np.uint8)[parity.astype(np.int64)]
    half = 0.5 * room.grid_line_width

    def near_edge(c: NDArray[np.float64]) -> NDArray[np.bool_]:
        return np.abs(c - room.tile_size * np.round(c / room.tile_size)) < half

    on_line = near_edge(y)[:, None] | near_edge(x)[None, :]
    image[on_line] = room.grid_colour_bgr
    return _Texture(image, (room.width, room.depth))


def _paint(
    image: NDArray[np.uint8],
    a_centres: NDArray[np.float64],
    z_centres: NDArray[np.float64],
    box: tuple[float, float, float, float],
    colour: Colour,
) -> None:
    """Paint texels whose centres lie in ``box = (a0, a1, z0, z1)`` (m), in place."""
    a0, a1, z0, z1 = box
    rows = (z_centres >= z0) & (z_centres <= z1)
    cols = (a_centres >= a0) & (a_centres <= a1)
    image[np.ix_(rows, cols)] = colour


def _outline(
    image: NDArray[np.uint8],
    a_centres: NDArray[np.float64],
    z_centres: NDArray[np.float64],
    box: tuple[float, float, float, float],
    colour: Colour,
    width: float,
) -> None:
    """Paint a rectangle's outline, lines ``width`` (m) wide centred on its edges."""
    a0, a1, z0, z1 = box
    h = 0.5 * width
    for edge in (
        (a0 - h, a1 + h, z0 - h, z0 + h),
        (a0 - h, a1 + h, z1 - h, z1 + h),
        (a0 - h, a0 + h, z0 - h, z1 + h),
        (a1 - h, a1 + h, z0 - h, z1 + h),
    ):
        _paint(image, a_centres, z_centres, edge, colour)


def _wall_texture(room: Room, wall: Wall) -> _Texture:
    """A wall seen from inside: row 0 at the ceiling, column 0 at ``a = 0``."""
    length = room.wall_length(wall.name)
    cols = max(2, round(length * room.texture_px_per_m))
    rows = max(2, round(room.height * room.texture_px_per_m))
    a = _texel_centres(cols, length)
    z = room.height - _texel_centres(rows, room.height)  # row 0 is the top
    image = np.empty((rows, cols, 3), dtype=np.uint8)
    image[...] = wall.colour_bgr
    w = room.feature_line_width
    line = room.line_colour_bgr
    for level in (room.skirting_height, room.rail_height):
        _paint(image, a, z, (0.0, length, level - w / 2, level + w / 2), line)
    for edge in (0.0, length):  # the room's vertical corners
        _paint(image, a, z, (edge - w / 2, edge + w / 2, 0.0, room.height), line)
    for opening in wall.openings:
        box = (*opening.a, *opening.z)
        if opening.kind == "door":
            _paint(image, a, z, box, room.door_colour_bgr)
        else:
            _paint(image, a, z, box, room.window_colour_bgr)
            a_mid, z_mid = 0.5 * sum(opening.a), 0.5 * sum(opening.z)
            _paint(image, a, z, (a_mid - w / 4, a_mid + w / 4, *opening.z), line)
            _paint(image, a, z, (*opening.a, z_mid - w / 4, z_mid + w / 4), line)
        _outline(image, a, z, box, line, w)
    scale, thickness = room._label_font(wall)
    origin = (
        round(wall.label_at[0] * cols / length),
        round((room.height - wall.label_at[1]) * rows / room.height),
    )
    cv2.putText(image, wall.label, origin, _LABEL_FONT, scale, line, thickness, cv2.LINE_AA)
    return _Texture(image, (length, room.height))


#: Face indices of the texture atlas, in its row order.
_FACES = ("floor", "N", "E", "S", "W", "ceiling")


@dataclass(frozen=True)
class _Atlas:
    """All surface textures stacked in one float32 image, for one ``cv2.remap`` lookup.

    Face ``k`` (in ``_FACES`` order) occupies rows ``row_offset[k] .. + rows[k] - 1`` and
    columns ``0 .. cols[k] - 1``; its texel ``(row, col)`` has its centre at
    ``((col + 0.5)/scale_s[k], (row + 0.5)/scale_t[k])`` metres from the face's top-left.
    """

    image: NDArray[np.float32]
    row_offset: NDArray[np.float64]
    rows: NDArray[np.float64]
    cols: NDArray[np.float64]
    scale_s: NDArray[np.float64]
    scale_t: NDArray[np.float64]


@functools.lru_cache(maxsize=4)
def _textures(room: Room) -> dict[str, _Texture]:
    """Read-only textures of the floor, the walls and the (plain) ceiling, built once."""
    textures = {"floor": _floor_texture(room)}
    for wall in room.walls:
        textures[wall.name] = _wall_texture(room, wall)
    ceiling = np.empty((2, 2, 3), dtype=np.uint8)
    ceiling[...] = room.ceiling_colour_bgr
    textures["ceiling"] = _Texture(ceiling, (room.width, room.depth))
    for texture in textures.values():
        texture.image.setflags(write=False)
    return textures


@functools.lru_cache(maxsize=4)
def _atlas(room: Room) -> _Atlas:
    """The room's textures stacked into one read-only atlas, built once per room."""
    textures = [_textures(room)[face] for face in _FACES]
    rows = np.array([t.image.shape[0] for t in textures], dtype=np.float64)
    cols = np.array([t.image.shape[1] for t in textures], dtype=np.float64)
    offsets = np.concatenate([[0.0], np.cumsum(rows)[:-1]])
    image = np.zeros((int(rows.sum()), int(cols.max()), 3), dtype=np.float32)
    for texture, offset in zip(textures, offsets, strict=True):
        r, c = texture.image.shape[:2]
        image[int(offset) : int(offset) + r, :c] = texture.image
    image.setflags(write=False)
    return _Atlas(
        image=image,
        row_offset=offsets,
        rows=rows,
        cols=cols,
        scale_s=cols / np.array([t.extent[0] for t in textures]),
        scale_t=rows / np.array([t.extent[1] for t in textures]),
    )


def _lookup(
    atlas: _Atlas, face: NDArray[np.int64], s: NDArray[np.float64], t: NDArray[np.float64]
) -> NDArray[np.float32]:
    """Bilinear colours at ``(s, t)`` metres from the top-left corner of each ray's face.

    Positions beyond a face's outermost texel centres take its edge texels' colour. The
    lookup is OpenCV's bilinear ``remap`` (interpolation weights in steps of 1/32 texel).

    Parameters
    ----------
    face : (N,) int ndarray
        Index into ``_FACES``.
    s, t : (N,) ndarray
        Position across and down the face (m).

    Returns
    -------
    (N, 3) float32 ndarray
        BGR colours.
    """
    n = face.shape[0]
    if n == 0:
        return np.zeros((0, 3), dtype=np.float32)
    col = np.clip(s * atlas.scale_s[face] - 0.5, 0.0, atlas.cols[face] - 1.0)
    row = np.clip(t * atlas.scale_t[face] - 0.5, 0.0, atlas.rows[face] - 1.0)
    row += atlas.row_offset[face]
    width = 1024  # cv2.remap wants maps narrower than 32767 pixels
    padded = -(-n // width) * width
    map_x = np.zeros(padded, dtype=np.float32)
    map_y = np.zeros(padded, dtype=np.float32)
    map_x[:n] = col
    map_y[:n] = row
    colours = cv2.remap(
        atlas.image,
        map_x.reshape(-1, width),
        map_y.reshape(-1, width),
        interpolation=cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_REPLICATE,
    )
    return np.asarray(colours, dtype=np.float32).reshape(-1, 3)[:n]


# ----------------------------------------------------------------------------------------
# Rendering
# ----------------------------------------------------------------------------------------


def render_rays(room: Room, origins: ArrayLike, directions: ArrayLike) -> NDArray[np.float32]:
    """Colours of the room surfaces hit by world rays.

    Parameters
    ----------
    origins : (..., 3) array_like
        Ray origins, world coordinates (m), inside the room (walls included).
    directions : (..., 3) array_like
        Ray directions, world axes (any length > 0).

    Returns
    -------
    (..., 3) float32 ndarray
        BGR colours in ``[0, 255]`` (bilinear texture lookup); 0 where the origin or
        direction holds a NaN or the direction is zero.

    Raises
    ------
    ValueError
        If a finite origin lies outside the room.
    """
    o, d = np.broadcast_arrays(np.asarray(origins, dtype=np.float64), np.asarray(directions, dtype=np.float64))
    if o.ndim == 0 or o.shape[-1] != 3:
        raise PanomapError(f"origins and directions must have shape (..., 3), got {o.shape}")
    shape = o.shape[:-1]
    o = o.reshape(-1, 3)
    d = d.reshape(-1, 3)
    out = np.zeros((o.shape[0], 3), dtype=np.float32)
    # Column-wise arithmetic: much faster than reductions over a length-3 axis.
    valid = (
        np.isfinite(o[:, 0] + o[:, 1] + o[:, 2])
        & np.isfinite(d[:, 0] + d[:, 1] + d[:, 2])
        & ((d[:, 0] != 0) | (d[:, 1] != 0) | (d[:, 2] != 0))
    )
    o, d = o[valid], d[valid]
    upper = (room.width, room.depth, room.height)
    if o.size and (o.min() < 0 or np.any(o.max(axis=0) > upper)):
        raise PanomapError("ray origins must lie inside the room")
    # Distance along the ray to the plane of the wall it heads for, per axis (inf if the
    # ray is parallel to it).
    t_axis = []
    positive = []
    for k in range(3):
        dk = d[:, k]
        pk = dk > 0
        tk = np.full(dk.shape, np.inf)
        np.divide(np.where(pk, upper[k], 0.0) - o[:, k], dk, out=tk, where=dk != 0)
        t_axis.append(tk)
        positive.append(pk)
    on_x = (t_axis[0] <= t_axis[1]) & (t_axis[0] <= t_axis[2])
    on_y = ~on_x & (t_axis[1] <= t_axis[2])
    on_z = ~on_x & ~on_y
    t = np.where(on_x, t_axis[0], np.where(on_y, t_axis[1], t_axis[2]))
    x = o[:, 0] + t * d[:, 0]
    y = o[:, 1] + t * d[:, 1]
    z = o[:, 2] + t * d[:, 2]
    # Face index in _FACES order: floor 0, N 1, E 2, S 3, W 4, ceiling 5.
    face = np.where(
        on_x,
        np.where(positive[0], 2, 4),
        np.where(on_y, np.where(positive[1], 1, 3), np.where(positive[2], 5, 0)),
    ).astype(np.int64)
    # Wall coordinate a (left to right seen from inside) and depth below the ceiling;
    # on the floor, (x, y).
    s_coord = np.where(
        on_x,
        np.where(positive[0], room.depth - y, y),
        np.where(on_y, np.where(positive[1], x, room.width - x), x),
    )
    t_coord = np.where(on_z, y, room.height - z)
    out[valid] = _lookup(_atlas(room), face, s_coord, t_coord)
    return out.reshape(*shape, 3)


def render(room: Room, camera: SimulatedCamera, supersample: int = 2) -> NDArray[np.uint8]:
    """Render the room as seen by a simulated camera at ``room.camera``.

    Each output pixel averages ``supersample**2`` rays traced at the centres of its
    sub-pixels (pixel ``(u, v)`` covers ``[u - 0.5, u + 0.5] x [v - 0.5, v + 0.5]``);
    sub-pixels outside the visible annulus count as black.

    Parameters
    ----------
    room : Room
        The room; the camera's O_m is ``room.camera``.
    camera : SimulatedCamera
        The camera.
    supersample : int
        Sub-pixels per pixel along each axis, >= 1.

    Returns
    -------
    (H, W, 3) uint8 ndarray
        BGR omni-image, ``(W, H) = camera.image_size``.
    """
    if not isinstance(supersample, int) or supersample < 1:
        raise PanomapError(f"supersample must be an integer >= 1, got {supersample!r}")
    width, height = camera.image_size
    sub = (np.arange(supersample) + 0.5) / supersample - 0.5
    du, dv = np.meshgrid(sub, sub)  # (ss, ss)
    o_m = np.asarray(room.camera, dtype=np.float64)
    image = np.zeros((height, width, 3), dtype=np.uint8)
    rows_per_chunk = max(1, _RAYS_PER_CHUNK // (width * supersample * supersample))
    u = np.arange(width, dtype=np.float64)
    for v_start in range(0, height, rows_per_chunk):
        v = np.arange(v_start, min(height, v_start + rows_per_chunk), dtype=np.float64)
        uu = u[None, :, None, None] + du[None, None]
        vv = v[:, None, None, None] + dv[None, None]
        uu, vv = np.broadcast_arrays(uu, vv)  # (rows, W, ss, ss)
        origins, directions = camera.trace(np.stack([uu, vv], axis=-1))
        colours = render_rays(room, origins + o_m, directions)
        colours = colours.reshape(len(v), width, supersample * supersample, 3)
        total = colours[:, :, 0].copy()
        for k in range(1, supersample * supersample):
            total += colours[:, :, k]
        mean = total / (supersample * supersample)
        image[v_start : v_start + len(v)] = np.clip(np.rint(mean), 0, 255).astype(np.uint8)
    return image
