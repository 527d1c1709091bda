"""Calibration readers, one file per format, declared once in :data:`READERS`; :func:`read_calibration`."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import NamedTuple

from ...errors import PanomapError
from ...files import read_text
from . import basalt, boofcv, colmap_cameras, gyroflow, hugin_pto, kalibr, ocam_txt, opencalib, opencv_storage
from .base import Imported, RigPose

Reader = Callable[[str, "str | Path", "str | None"], Imported]


class Format(NamedTuple):
    """A format: does the text look like it, read it, and whether a file of it may hold several cameras
    (picked by ``--camera-name``/``--camera-id``)."""

    looks_like: Callable[[str], bool]
    read: Reader
    many_cameras: bool = False


# Every format by name. Detection tries them in this order: gyroflow's JSON before OpenCV's, whose JSON
# detection (a ``"camera_matrix":`` line) a profile's nested ``fisheye_params`` would also meet.
READERS: dict[str, Format] = {
    "ocam": Format(ocam_txt.looks_like, ocam_txt.read),
    "gyroflow": Format(gyroflow.looks_like, gyroflow.read),
    "opencv": Format(opencv_storage.looks_like, opencv_storage.read),
    "kalibr": Format(kalibr.looks_like, kalibr.read, many_cameras=True),
    "colmap": Format(colmap_cameras.looks_like, colmap_cameras.read, many_cameras=True),
    "boofcv": Format(boofcv.looks_like, boofcv.read),
    "basalt": Format(basalt.looks_like, basalt.read, many_cameras=True),
    "hugin": Format(hugin_pto.looks_like, hugin_pto.read, many_cameras=True),
    "opencalib": Format(opencalib.looks_like, opencalib.read),
}


def read_calibration(path: str | Path, format: str | None = None, camera: str | None = None) -> Imported:
    """The calibration in ``path``: its format from the content unless ``format`` (a key of READERS)
    forces it; ``camera`` picks a Kalibr, Basalt or Hugin camera (name or index) or a COLMAP camera id."""
    text = read_text(path)
    if format is None:
        found = [name for name, entry in READERS.items() if entry.looks_like(text)]
        if not found:
            raise PanomapError(f"not a calibration this reads ({', '.join(READERS)}); give --format to force one", path)
        format = found[0]
    if format not in READERS:
        raise PanomapError(f"unknown calibration format {format!r} (known: {', '.join(READERS)})")
    if camera is not None and not READERS[format].many_cameras:
        raise PanomapError(f"a {format} file holds one camera: --camera-name/--camera-id do not apply", path)
    return READERS[format].read(text, path, camera)


__all__ = ["READERS", "Format", "Imported", "RigPose", "read_calibration"]
