"""Rigs (beyond the paper): several cameras, a table each, in one world frame, and their views blended.

:mod:`.rig` (:class:`CameraRig`), :mod:`.file` (:func:`save_rig`, :func:`load_rig`), :mod:`.blend` (each
camera's map of a view, the feathered weights, the gains, :class:`RigRemapper`).
"""

from .blend import RigRemapper, camera_maps
from .file import is_rig_file, load_rig, save_rig
from .rig import CameraRig

__all__ = ["CameraRig", "RigRemapper", "camera_maps", "is_rig_file", "load_rig", "save_rig"]
