"""Hugin's (and PTGui's) PanoTools project ``.pto``: one ``i`` line per image, each image a camera.

Read from each ``i`` line: ``w``, ``h`` (px), ``f`` (the projection: 0 rectilinear, 2 circular fisheye,
3 full-frame fisheye; others are refused), ``v`` (hfov, deg), ``a b c`` (the radial polynomial), ``d e`` (the
centre's shift, px), ``g t`` (shear: refused unless 0), ``y p r`` (yaw, pitch, roll, deg), ``TrX TrY TrZ``
(a mosaic's camera translation: refused unless 0). A value ``=N`` is image N's (Hugin links a lens's values
so). The model is :class:`..models.panotools.PanoToolsFisheye` (or its rectilinear kin); the ``p`` line (the
output panorama) and the rest are not read. The cameras are named ``cam0``, ``cam1``, ... in the file's order;
``--camera-name`` takes a name or an index (default the first).

PanoTools' yaw, pitch and roll (Hugin ``SpaceTransform::Init``, libpano13 ``SetMatrix``): a panorama's direction at
longitude ``lon`` (to the right) and latitude ``lat`` (up) has, in the image's frame (x right, y down, z ahead),
the ray ``M^T P``, where ``P = (cos lat sin(lon - y), -sin lat, cos lat cos(lon - y))`` and
``M = Rx(-p) Rz(-r)`` (libpano13's ``mx``, ``mz``: rows ``(1, 0, 0), (0, cos, sin), (0, -sin, cos)`` and
``(cos, sin, 0), (-sin, cos, 0), (0, 0, 1)``). So yaw turns the camera to the right, pitch up, roll dips the
image's right: in panomap's world (the panorama's centre along +X, Z up, azimuth ``-lon``) a camera of
``y, p, r`` looks yaw ``-y``, pitch ``p``, roll ``r`` (:func:`axes_of_ypr`).
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from ...errors import PanomapError
from ...geometry import FloatArray
from ..models.base import ExternalCamera
from ..models.panotools import PanoToolsFisheye, PanoToolsRectilinear
from .base import Imported, built, image_size_of, number

PROJECTIONS = {0: "rectilinear", 2: "circular fisheye", 3: "full-frame fisheye"}
OTHER_PROJECTIONS = {1: "cylindrical", 4: "equirectangular", 8: "orthographic", 10: "stereographic",
                     19: "equisolid", 20: "fisheye Thoby"}  # fmt: skip
KEYS = ("w", "h", "f", "v", "y", "p", "r", "a", "b", "c", "d", "e", "g", "t")
DEFAULTS = {"y": 0.0, "p": 0.0, "r": 0.0, "a": 0.0, "b": 0.0, "c": 0.0, "d": 0.0, "e": 0.0, "g": 0.0, "t": 0.0}
# The most images a project may hold here.
MAX_IMAGES = 64
_TOKEN = re.compile(r'[A-Za-z]+"[^"]*"|\S+')
_IMAGE_LINE = re.compile(r"^i\s.*\bw\d+\s.*\bh\d+", re.MULTILINE)


def looks_like(text: str) -> bool:
    """Whether ``text`` reads as a PanoTools project: an ``i`` line with ``w`` and ``h``, and a ``p`` line."""
    return _IMAGE_LINE.search(text) is not None and re.search(r"^p\s", text, re.MULTILINE) is not None


def read_images(text: str, path: str | Path) -> list[tuple[Imported, tuple[float, float, float]]]:
    """Every image of the project, in its order: its camera, and its (yaw, pitch, roll) in degrees, PanoTools'."""
    lines = [line for line in text.splitlines() if line.startswith("i ") or line.startswith("i\t")]
    if not lines:
        raise PanomapError("no image (no i line): not a PanoTools project", path)
    if len(lines) > MAX_IMAGES:
        raise PanomapError(f"{len(lines)} images: at most {MAX_IMAGES} are read", path)
    images: list[dict[str, float]] = []
    out = []
    for k, line in enumerate(lines):
        values = _values(line, k, images, path)
        images.append(values)
        out.append((_camera(values, k, path), (values["y"], values["p"], values["r"])))
    return out


def read(text: str, path: str | Path, choice: str | None = None) -> Imported:
    images = read_images(text, path)
    index = 0
    if choice is not None:
        digits = choice[3:] if choice.startswith("cam") else choice
        if not (digits.isdigit() and int(digits) < len(images)):
            names = ", ".join(f"cam{i}" for i in range(len(images)))
            raise PanomapError(f"no camera {choice!r} (it has {names}, or their indices)", path)
        index = int(digits)
    return images[index][0]


def axes_of_ypr(yaw_deg: float, pitch_deg: float, roll_deg: float) -> FloatArray:
    """G (3, 3): the image's frame axes (columns: right, down, ahead) in panomap's world, of PanoTools' yaw, pitch
    and roll (deg), written from PanoTools' stack (the module's docstring)."""
    y, p, r = (math.radians(x) for x in (yaw_deg, pitch_deg, roll_deg))
    rx = np.array([[1.0, 0.0, 0.0], [0.0, math.cos(-p), math.sin(-p)], [0.0, -math.sin(-p), math.cos(-p)]])
    rz = np.array([[math.cos(-r), math.sin(-r), 0.0], [-math.sin(-r), math.cos(-r), 0.0], [0.0, 0.0, 1.0]])
    # P -> the panorama's own frame (right, down, ahead) at longitude lon = lon' + y: a turn about "down".
    turn = np.array([[math.cos(y), 0.0, math.sin(y)], [0.0, 1.0, 0.0], [-math.sin(y), 0.0, math.cos(y)]])
    # The panorama's (right, down, ahead) in panomap's world: ahead +X, right -Y, down -Z.
    world = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    return world @ turn @ rx @ rz


def _values(line: str, k: int, images: list[dict[str, float]], path: str | Path) -> dict[str, float]:
    """The line's values by key (defaults where missing), ``=N`` resolved to image N's."""
    values: dict[str, float] = {}
    for token in _TOKEN.findall(line[1:]):
        if token[0].isupper():
            key = re.match(r"[A-Z][a-z]*[A-Z]?", token).group(0)  # type: ignore[union-attr]
            if key in ("TrX", "TrY", "TrZ"):
                value = _value(token[len(key) :], f"image {k}'s {key}", k, images, key, path, allow_link=False)
                if value != 0:
                    raise PanomapError(
                        f"image {k}'s {key} is {value:g}: a mosaic's camera translation is not read", path
                    )
            continue
        key = token[0]
        if key not in KEYS or len(token) == 1:
            continue
        values[key] = _value(token[1:], f"image {k}'s {key}", k, images, key, path)
    for key in KEYS:
        if key not in values:
            if key not in DEFAULTS:
                raise PanomapError(f"image {k}'s {key} is missing", path)
            values[key] = DEFAULTS[key]
    return values


def _value(
    text: str, where: str, k: int, images: list[dict[str, float]], key: str, path: str | Path, allow_link: bool = True
) -> float:
    if text.startswith("=") and allow_link:
        link = text[1:]
        if not link.isdigit() or int(link) >= k:
            raise PanomapError(f"{where} is {text!r}: a link names an image before it", path)
        return images[int(link)][key]
    return number(text, where, path)


def _camera(values: dict[str, float], k: int, path: str | Path) -> Imported:
    projection = values["f"]
    if projection not in PROJECTIONS:
        name = OTHER_PROJECTIONS.get(int(projection), "unknown") if projection == int(projection) else "unknown"
        known = ", ".join(f"{n} {label}" for n, label in PROJECTIONS.items())
        raise PanomapError(f"image {k}'s projection f{projection:g} ({name}) is not read (it reads {known})", path)
    for key in ("g", "t"):
        if values[key] != 0:
            raise PanomapError(f"image {k}'s shear {key} is {values[key]:g}: a sheared image is not read", path)
    width, height = image_size_of(values["w"], values["h"], f"image {k}'s w x h", path)
    hfov = math.radians(values["v"])
    rectilinear = projection == 0
    if not 0 < hfov < (math.pi if rectilinear else 2 * math.pi):
        limit = 180 if rectilinear else 360
        raise PanomapError(f"image {k}'s hfov v is {values['v']:g} deg: it must lie in (0, {limit})", path)
    f = width / 2 / math.tan(hfov / 2) if rectilinear else width / hfov
    cls: type[ExternalCamera] = PanoToolsRectilinear if rectilinear else PanoToolsFisheye
    cx = width / 2 - 0.5 + values["d"]
    cy = height / 2 - 0.5 + values["e"]
    model = built(cls, path, f, cx, cy, values["a"], values["b"], values["c"], min(width, height) / 2)
    return Imported(model, "hugin", (width, height), f"cam{k}")
