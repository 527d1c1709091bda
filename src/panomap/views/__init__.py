"""Views (paper 2.3 and beyond): what ray each output pixel sees, the maps that follow, and view specs.

One file per kind: :mod:`.panorama`, :mod:`.cylinder`, :mod:`.plane`,
:mod:`.perspective`, :mod:`.floor`, :mod:`.equirect`; :mod:`.base` holds what they share and the
one registry of kinds, which importing this package fills (in this order).
"""

from .base import Band, View, build_map, view_kinds

# The kinds, registered in this order (the order specs and commands list them).
# isort: off
from .panorama import GenericPanorama
from .cylinder import CylinderPanorama
from .plane import PlaneView
from .perspective import PerspectiveView
from .floor import FloorView
from .equirect import EquirectView

# isort: on

__all__ = [
    "Band",
    "CylinderPanorama",
    "EquirectView",
    "FloorView",
    "GenericPanorama",
    "PerspectiveView",
    "PlaneView",
    "View",
    "build_map",
    "view_kinds",
]
