"""Views described in one argument or in a small file of named views.

A view SPEC is ``KIND:key=value,key=value,...`` (``KIND`` alone where every
key has a default), with the parameters each kind declares (the options of
its command: ``distance=2`` is ``--distance 2``), angles in degrees and
lengths in world units, as on the command line::

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
from .base import Value, View, view_kinds

NAME_PATTERN = re.compile(r"^[A-Za-z0-9_-]+$")


@dataclass(frozen=True)
class NamedView:
    """A view with the name of its output."""

    name: str
    view: View

    def __post_init__(self) -> None:
        if self.name is not None and not isinstance(self.name, str):
            raise TypeError(f"a view's name must be text, not {type(self.name).__name__}")
        if not isinstance(self.view, View):
            raise TypeError(
                f"a named view's view must be a View, not {type(self.view).__name__}: parse_view_spec reads a spec"
            )


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


# How a spec writes each type of value: (key, raw value) -> the view's value.
PARSERS: dict[Value, Callable[[str, Any], Any]] = {
    Value.NUMBER: _number,
    Value.ANGLE: _deg,
    Value.PAIR: _pair,
    Value.SIZE: _size,
}
KINDS = tuple(view_kinds())


def view_from_params(kind: str, params: Mapping[str, Any]) -> View:
    """Build the view of ``kind`` from raw parameters (strings or JSON values).

    Angles are in degrees, lengths in world units; unknown or missing keys are
    errors that name them.
    """
    cls = view_kinds().get(kind)
    if cls is None:
        raise PanomapError(f"unknown view kind {kind!r}: choose one of {', '.join(KINDS)}")
    declared = {param.name: param for param in cls.params}
    unknown = sorted(set(params) - set(declared))
    if unknown:
        raise PanomapError(f"a {kind} view has no key {', '.join(unknown)} (keys: {', '.join(sorted(declared))})")
    missing = [param.name for param in cls.params if param.required and param.name not in params]
    if missing:
        raise PanomapError(f"a {kind} view needs {', '.join(f'{key}=' for key in missing)}")
    parsed = {key: PARSERS[declared[key].value](key, value) for key, value in params.items() if value is not None}
    if cls.one_of is not None and sum(key in parsed for key in cls.one_of.names) != 1:
        needs = " or ".join(f"{key}={declared[key].shown_as}" for key in cls.one_of.names)
        raise PanomapError(f"a {kind} view needs {needs}, {cls.one_of.how_many}")
    defaults = {
        param.name: None if param.default is None else PARSERS[param.value](param.name, param.default)
        for param in cls.params
    }
    return cls.from_params(defaults | parsed)


def _check_name(name: str) -> str:
    if not NAME_PATTERN.match(name):
        raise PanomapError(f"view name {name!r} may hold only letters, digits, '-' and '_'")
    return name


def parse_view_spec(spec: str) -> tuple[str | None, View]:
    """``KIND:key=value,...`` to (the name it gives or None, the view).

    Parameters
    ----------
    spec : str
        A view SPEC, as ``panomap video --view`` takes it: the view kind (``panorama``, ``cylinder``,
        ``plane``, ``perspective``, ``floor``), then the keys of its command's options (angles in degrees,
        pairs ``A:B``, sizes ``WxH``) and optionally ``name``, e.g.
        ``perspective:yaw=30,pitch=-20,fov=90,size=1280x720,name=door``.

    Returns
    -------
    name : str or None
        The ``name`` the SPEC gives, where it gives one.
    view : View
        The view.

    Raises
    ------
    PanomapError
        Naming the SPEC and what is wrong with it: an unknown kind or key, a value out of range.
    """
    if not isinstance(spec, str):
        raise TypeError(f"a view spec must be text (KIND:key=value,...), not {type(spec).__name__}")
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
    kinds = [view.kind for _, view in specs]
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
