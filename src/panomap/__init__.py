"""panomap: unwarp omni-images with pano-mapping tables (Jeng & Tsai, 2007, and beyond).

The pieces, in the paper's order:

- :class:`Landmarks`, :func:`read_landmarks`: landmark point pairs (2.1).
- :func:`fit_camera` -> :class:`CameraFit` (Algorithm 1), with its
  :class:`CameraModel` and :class:`RadialFunction`.
- :func:`create_table` -> :class:`PanoMappingTable` (Algorithm 2);
  :func:`load_table`, ``table.save``.
- Views (2.3): :class:`GenericPanorama`, :class:`CylinderPanorama`,
  :class:`PlaneView`, and beyond the paper :class:`PerspectiveView` (a virtual
  pan-tilt-zoom camera) and :class:`FloorView` (a bird's-eye map);
  :func:`build_map`, and ``view.remapper(table)`` (a :class:`Remapper`) to apply
  them to any number of frames.
- Pixels back to rays: ``table.unproject(uv)``.

Conventions are in :mod:`panomap.geometry` and ``docs/conventions.md``.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"

# Each name and the module that defines it. They are imported on first use
# (PEP 562), so that ``import panomap`` and the command line pay only for what
# they use (``panomap video`` never loads the fitting code).
_EXPORTS = {
    "Band": "views",
    "CameraFit": "fit",
    "CameraModel": "model",
    "CylinderPanorama": "views",
    "FloorView": "views",
    "GenericPanorama": "views",
    "Landmarks": "landmarks",
    "PanoMappingTable": "table",
    "PanomapError": "errors",
    "PerspectiveView": "views",
    "PlaneView": "views",
    "RadialFunction": "radial",
    "Remapper": "remap",
    "build_map": "views",
    "create_table": "table",
    "fit_camera": "fit",
    "load_table": "table",
    "read_landmarks": "landmarks",
}

__all__ = [
    "Band",
    "CameraFit",
    "CameraModel",
    "CylinderPanorama",
    "FloorView",
    "GenericPanorama",
    "Landmarks",
    "PanoMappingTable",
    "PanomapError",
    "PerspectiveView",
    "PlaneView",
    "RadialFunction",
    "Remapper",
    "__version__",
    "build_map",
    "create_table",
    "fit_camera",
    "load_table",
    "read_landmarks",
]


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted([*globals(), *_EXPORTS])


if TYPE_CHECKING:
    from .errors import PanomapError
    from .fit import CameraFit, fit_camera
    from .landmarks import Landmarks, read_landmarks
    from .model import CameraModel
    from .radial import RadialFunction
    from .remap import Remapper
    from .table import PanoMappingTable, create_table, load_table
    from .views import Band, CylinderPanorama, FloorView, GenericPanorama, PerspectiveView, PlaneView, build_map
