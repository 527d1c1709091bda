"""Calibration readers, one file per format, declared once in :data:`READERS`; :func:`read_calibration`."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from ...errors import PanomapError
from ...files import read_text
from . import colmap_cameras, kalibr, ocam_txt, opencv_storage
from .base import Imported

Reader = Callable[[str, "str | Path", "str | None"], Imported]

# Every format: name -> (does the text look like it, read it). Detection tries them in this order.
READERS: dict[str, tuple[Callable[[str], bool], Reader]] = {
    "ocam": (ocam_txt.looks_like, ocam_txt.read),
    "opencv": (opencv_storage.looks_like, opencv_storage.read),
    "kalibr": (kalibr.looks_like, kalibr.read),
    "colmap": (colmap_cameras.looks_like, colmap_cameras.read),
}


def read_calibration(path: str | Path, format: str | None = None, camera: str | None = None) -> Imported:
    """The calibration in ``path``: its format from the content unless ``format`` (a key of READERS)
    forces it; ``camera`` picks a Kalibr camera name or a COLMAP camera id."""
    text = read_text(path)
    if format is None:
        found = [name for name, (looks_like, _) in READERS.items() if looks_like(text)]
        if not found:
            raise PanomapError(f"not a calibration this reads ({', '.join(READERS)}); give --format to force one", path)
        format = found[0]
    if format not in READERS:
        raise PanomapError(f"unknown calibration format {format!r} (known: {', '.join(READERS)})")
    if camera is not None and format not in ("kalibr", "colmap"):
        raise PanomapError(f"a {format} file holds one camera: --camera-name/--camera-id do not apply", path)
    return READERS[format][1](text, path, camera)


__all__ = ["READERS", "Imported", "read_calibration"]
