"""panomap: unwarp omni-images with pano-mapping tables (Jeng & Tsai, 2007, and beyond).

The pieces, in the paper's order:

- :class:`Landmarks`, :func:`read_landmarks`: landmark point pairs (2.1).
- :func:`fit_camera` -> :class:`CameraFit` (Algorithm 1), with its
  :class:`CameraModel` and :class:`RadialFunction`.
- :func:`create_table` -> :class:`PanoMappingTable` (Algorithm 2);
  :func:`load_table`, :func:`save_table`.
- :func:`calibrate_camera` -> :class:`Calibration`: the whole step, from landmarks
  and an omni-image (its circles found when the centre or radii are not
  given (:func:`choose_circles` -> :class:`CircleChoice`; :class:`NoImageCircle` where no rim
  shows), each one's :class:`Source` recorded) to the fit and its table.
- :func:`learn_from_images` -> :class:`LearnedCalibration`: the same without landmarks, the camera
  learned from the straight lines and checkerboards of one or more pictures.
- Views (2.3): :class:`GenericPanorama`, :class:`CylinderPanorama`,
  :class:`PlaneView`, and beyond the paper :class:`PerspectiveView` (a virtual
  pan-tilt-zoom camera) and :class:`FloorView` (a bird's-eye map);
  :func:`build_map`, and ``view.remapper(table)`` (a :class:`Remapper`) to apply
  them to any number of frames.
- Pixels back to rays: ``table.unproject(uv)``.
- Other tools' calibrations (OCamCalib, OpenCV, Kalibr, COLMAP): :func:`import_calibration` makes
  a table of one, :func:`export_calibration` fits one to a table (:mod:`panomap.interop`).
- Video: :func:`unwarp_video` (which frames: :class:`Selection`; each view's file:
  :class:`ViewOutput`, :class:`EncoderSettings`); many inputs at once, on Dask, resumably:
  :func:`find_inputs`, :func:`make_job` (its :class:`Settings`), :class:`Record`, :func:`run_job` ->
  :class:`BatchReport` (:mod:`panomap.batch`).

Conventions are in :mod:`panomap.geometry` and ``docs/conventions.md``.
"""

from __future__ import annotations

import importlib
from typing import Any

__version__ = "0.1.0"

# The public API, in the order of the chain: each name and the module that defines it.
# Names are imported on first use (PEP 562), so that ``import panomap`` and the command
# line pay only for what they use (``panomap video`` never loads the fitting code).
_EXPORTS = {
    # errors
    "PanomapError": "errors",
    # images in
    "read_image": "io.images",
    "write_image": "io.images",
    # calibrate: circles, landmarks, the fit, the table made from them
    "Circle": "calibrate.circles",
    "ImageCircles": "calibrate.circles",
    "NoImageCircle": "calibrate.circles",
    "find_image_circles": "calibrate.circles",
    "Landmarks": "calibrate.landmarks.pairs",
    "read_landmarks": "calibrate.landmarks.pairs",
    "CameraFit": "calibrate.landmarks.fit",
    "FitReport": "calibrate.core.report",
    "fit_camera": "calibrate.landmarks.fit",
    "Source": "calibrate.core.sources",
    "SphericalMirror": "calibrate.landmarks.viewpoint",
    "CircleChoice": "calibrate.landmarks.pipeline",
    "choose_circles": "calibrate.landmarks.pipeline",
    "Calibration": "calibrate.landmarks.pipeline",
    "calibrate_camera": "calibrate.landmarks.pipeline",
    # a camera learned from pictures (lines, checkerboards), no landmark
    "LearnedCalibration": "calibrate.pictures",
    "learn_from_images": "calibrate.pictures",
    # the camera model
    "CameraModel": "camera.model",
    "RadialFunction": "camera.radial",
    # the table
    "PanoMappingTable": "table.table",
    "create_table": "calibrate.landmarks.table",
    "load_table": "table.file",
    "save_table": "table.file",
    # views and their maps
    "Band": "views.base",
    "GenericPanorama": "views.panorama",
    "CylinderPanorama": "views.cylinder",
    "PlaneView": "views.plane",
    "PerspectiveView": "views.perspective",
    "FloorView": "views.floor",
    "EquirectView": "views.equirect",
    "build_map": "views.base",
    "NamedView": "views.spec",
    "parse_view_spec": "views.spec",
    "Remapper": "remap",
    # video
    "Selection": "video.source",
    "EncoderSettings": "video.output",
    "ViewOutput": "video.unwarp",
    "Reconnect": "video.live",
    "Gap": "video.report",
    "unwarp_video": "video.unwarp",
    # batches, on Dask
    "find_inputs": "batch.job",
    "make_job": "batch.job",
    "Settings": "batch.job",
    "Record": "batch.record",
    "run_job": "batch.run",
    "RunSettings": "batch.run",
    "BatchReport": "batch.run",
    # other tools' calibrations in and out (issue 36)
    "import_calibration": "interop.api",
    "export_calibration": "interop.export",
    # cameras that look any way (issue 51)
    "orient_table": "interop.orient",
    "level_table": "calibrate.level",
    "LevelResult": "calibrate.level",
    # rigs: several cameras in one world (issue 52)
    "CameraRig": "rig.rig",
    "load_rig": "rig.file",
    "save_rig": "rig.file",
    "camera_maps": "rig.blend",
    "RigRemapper": "rig.blend",
    "rig_of_camchain": "interop.rig_of_camchain",
}

__all__ = ["__version__", *_EXPORTS]


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted([*globals(), *_EXPORTS])
