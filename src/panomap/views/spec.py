"""Views described in one argument or in a small file of named views.

A view SPEC is ``KIND:key=value,key=value,...`` (``KIND`` alone where every
key has a default), with the keys of the matching view command, angles in
degrees and lengths in world units, as on the command line::

    panorama:size=2048x512,start=0
    cylinder:distance=2,band=-2.45:0.15,size=2048x560,start=0
    plane:distance=1.8,width=2.4,band=-2.45:0.15,azimuth=90,size=800x860
    perspective:yaw=30,pitch=-20,roll=0,fov=90,size=1280x720
    floor:z=0,x=0:6,y=0:5,size=1200x1000        (or resolution=0.005)

Every spec may also carry ``name=NAME`` (letters, digits, ``-`` and ``_``),
which names its output; the default name is the kind, numbered when two
views share it. Pairs of numbers (``band``, ``x``, ``y``) are written
``A:B``; sizes ``WxH``.

A views file (JSON, or YAML where the name ends in ``.yaml``/``.yml``) maps
names to the same keys plus ``kind``, with numbers as numbers, pairs as
two-element lists or ``A:B`` strings and sizes as ``[W, H]`` or ``WxH``::

    {"door": {"kind": "perspective", "yaw": 90, "pitch": -20, "fov": 90,
              "size": "1280x720"},
     "pano": {"kind": "panorama", "size": [2048, 512]}}
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..errors import PanomapError
from ..files import read_text
from ..values import NotFinite, finite_number
from .views import Band, CylinderPanorama, FloorView, GenericPanorama, PerspectiveView, PlaneView, View

NAME_PATTERN = re.compile(r"^[A-Za-z0-9_-]+$")


@dataclass(frozen=True)
class NamedView:
    """A view with the name of its output."""

    name: str
    view: View


def _number(key: str, value: Any) -> float:
    try:
        return finite_number(value, bools=False)
    except NotFinite as exc:
        raise PanomapError(f"{key}={exc}") from None


def _pair(key: str, value: Any) -> tuple[float, float]:
    parts = value.split(":") if isinstance(value, str) else value
    if not isinstance(parts, list | tuple) or len(parts) != 2:
        raise PanomapError(f"{key}={value!r} is not a pair like A:B")
    return _number(key, parts[0]), _number(key, parts[1])


def _size(key: str, value: Any) -> tuple[int, int]:
    parts = value.lower().split("x") if isinstance(value, str) else value
    try:
        if not isinstance(parts, list | tuple) or len(parts) != 2:
            raise ValueError
        width, height = (int(p) for p in parts)
    except (TypeError, ValueError):
        raise PanomapError(f"{key}={value!r} is not a size like 1280x720") from None
    return width, height


def _deg(key: str, value: Any) -> float:
    return math.radians(_number(key, value))


# kind -> (required keys, optional keys with defaults, constructor from parsed values)
_Parsers = dict[str, Callable[[str, Any], Any]]
_PARSERS: _Parsers = {
    "size": _size,
    "start": _deg,
    "distance": _number,
    "band": _pair,
    "width": _number,
    "azimuth": _deg,
    "yaw": _deg,
    "pitch": _deg,
    "roll": _deg,
    "fov": _deg,
    "z": _number,
    "x": _pair,
    "y": _pair,
    "resolution": _number,
}


def _floor(p: dict[str, Any]) -> View:
    if ("size" in p) == ("resolution" in p):
        raise PanomapError("a floor view needs size=WxH or resolution=R, one of the two")
    if "size" in p:
        return FloorView(p["z"], p["x"], p["y"], p["size"])
    return FloorView.with_resolution(p["z"], p["x"], p["y"], p["resolution"])


_KINDS: dict[str, tuple[tuple[str, ...], dict[str, Any], Callable[[dict[str, Any]], View]]] = {
    "panorama": ((), {"size": None, "start": 0.0}, lambda p: GenericPanorama(p["size"], p["start"])),
    "cylinder": (
        ("distance", "band", "size"),
        {"start": 0.0},
        lambda p: CylinderPanorama(p["distance"], Band(*p["band"]), p["size"], p["start"]),
    ),
    "plane": (
        ("distance", "width", "band", "azimuth", "size"),
        {},
        lambda p: PlaneView(p["distance"], p["width"], Band(*p["band"]), p["azimuth"], p["size"]),
    ),
    "perspective": (
        ("yaw", "pitch", "fov", "size"),
        {"roll": 0.0},
        lambda p: PerspectiveView(p["yaw"], p["pitch"], p["roll"], p["fov"], p["size"]),
    ),
    "floor": (("z", "x", "y"), {"size": None, "resolution": None}, _floor),
}
KINDS = tuple(_KINDS)


def view_from_params(kind: str, params: Mapping[str, Any]) -> View:
    """Build the view of ``kind`` from raw parameters (strings or JSON values).

    Angles are in degrees, lengths in world units; unknown or missing keys are
    errors that name them.
    """
    if kind not in _KINDS:
        raise PanomapError(f"unknown view kind {kind!r}: choose one of {', '.join(KINDS)}")
    required, defaults, make = _KINDS[kind]
    allowed = set(required) | set(defaults)
    unknown = sorted(set(params) - allowed)
    if unknown:
        raise PanomapError(f"a {kind} view has no key {', '.join(unknown)} (keys: {', '.join(sorted(allowed))})")
    missing = [key for key in required if key not in params]
    if missing:
        raise PanomapError(f"a {kind} view needs {', '.join(f'{key}=' for key in missing)}")
    parsed = {key: _PARSERS[key](key, value) for key, value in params.items() if value is not None}
    values = {key: value for key, value in defaults.items() if value is not None} | parsed
    if kind == "floor":
        return make(parsed)
    return make({**{key: None for key in defaults}, **values})


def _check_name(name: str) -> str:
    if not NAME_PATTERN.match(name):
        raise PanomapError(f"view name {name!r} may hold only letters, digits, '-' and '_'")
    return name


def parse_view_spec(spec: str) -> tuple[str | None, View]:
    """``KIND:key=value,...`` to (the name it gives or None, the view)."""
    kind, _, rest = spec.strip().partition(":")
    params: dict[str, str] = {}
    for item in filter(None, (part.strip() for part in rest.split(","))):
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise PanomapError(f"view spec {spec!r}: {item!r} is not key=value")
        if key.strip() in params:
            raise PanomapError(f"view spec {spec!r}: {key.strip()} is given twice")
        params[key.strip()] = value.strip()
    name = params.pop("name", None)
    try:
        view = view_from_params(kind.strip(), params)
    except PanomapError as exc:
        raise PanomapError(f"view spec {spec!r}: {exc}") from None
    return (_check_name(name) if name is not None else None), view


def read_views_file(path: str | Path) -> list[NamedView]:
    """Named views from a JSON (or YAML: ``.yaml``/``.yml``) file; see the module docstring."""
    path = Path(path)
    text = read_text(path)
    try:
        if path.suffix.lower() in (".yaml", ".yml"):
            import yaml

            data = yaml.safe_load(text)
        else:
            data = json.loads(text)
    except Exception as exc:  # any parse error is the file's problem
        raise PanomapError(
            f"not valid {'YAML' if path.suffix.lower() in ('.yaml', '.yml') else 'JSON'}: {' '.join(str(exc).split())}",
            path,
        ) from None
    if not isinstance(data, dict) or not data:
        raise PanomapError("it must map view names to their parameters", path)
    views = []
    for name, params in data.items():
        if not isinstance(params, dict) or "kind" not in params:
            raise PanomapError(f"view {name!r} must be a mapping with a 'kind'", path)
        params = dict(params)
        kind = str(params.pop("kind"))
        try:
            views.append(NamedView(_check_name(str(name)), view_from_params(kind, params)))
        except PanomapError as exc:
            raise PanomapError(f"view {name!r}: {exc}", path) from None
    return views


def name_views(specs: list[tuple[str | None, View]]) -> list[NamedView]:
    """Give every unnamed view its kind's name, numbered where kinds repeat; names must be unique."""
    kinds = [_kind_of(view) for _, view in specs]
    named: list[NamedView] = []
    for index, ((name, view), kind) in enumerate(zip(specs, kinds, strict=True)):
        if name is None:
            name = kind if kinds.count(kind) == 1 else f"{kind}{kinds[: index + 1].count(kind)}"
        named.append(NamedView(name, view))
    names = [item.name for item in named]
    repeated = sorted({name for name in names if names.count(name) > 1})
    if repeated:
        raise PanomapError(f"two views are named {', '.join(repeated)}: give each a different name=")
    return named


def _kind_of(view: View) -> str:
    return {
        GenericPanorama: "panorama",
        CylinderPanorama: "cylinder",
        PlaneView: "plane",
        PerspectiveView: "perspective",
        FloorView: "floor",
    }[type(view)]
