"""The table file: a NumPy ``.npz`` holding ``entries`` and ``meta``.

``meta`` is JSON text with ``format = "panomap-table"``, ``version``, the
model, the elevation range, radii, image size, camera position, the table's
``info`` (where the centre and radii came from, the landmarks and the fit
report), and the SHA-256 of ``entries``. Loading checks all of it and that the
entries are what the model gives.
"""

from __future__ import annotations

import hashlib
import json
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..camera.model import CameraModel
from ..errors import PanomapError
from ..files import write_with
from .table import PanoMappingTable, fill_entries

TABLE_FORMAT = "panomap-table"
TABLE_VERSION = 1
# Entries are float32: about 1e-4 px at radii of 2000 px. A loaded table whose
# entries stray further than this from its own model is corrupt.
ENTRY_TOLERANCE_PX = 1e-2


def table_metadata(table: PanoMappingTable) -> dict[str, Any]:
    """Everything but the entries, as JSON-ready data (angles in rad)."""
    m, n = table.size
    return {
        "format": TABLE_FORMAT,
        "version": TABLE_VERSION,
        "size": [m, n],
        "elevation_range_rad": list(table.elevation_range),
        "model": table.model.to_dict(),
        "camera_position": list(table.camera_position),
        "image_size": None if table.image_size is None else list(table.image_size),
        "cutoff_radius_px": table.cutoff_radius,
        "outer_radius_px": table.outer_radius,
        "info": table.info,
    }


def save_table(table: PanoMappingTable, path: str | Path) -> None:
    """Write the table to ``path`` (an ``.npz``), through a temporary file."""
    meta = table_metadata(table) | {"entries_sha256": _digest(table.entries)}
    text = json.dumps(meta, indent=1, allow_nan=False)

    def writer(handle: Any) -> None:
        np.savez(handle, entries=table.entries, meta=np.array(text))

    write_with(path, writer)


def _digest(entries: NDArray[np.float32]) -> str:
    return hashlib.sha256(np.ascontiguousarray(entries, dtype="<f4").data).hexdigest()


def load_table(path: str | Path) -> PanoMappingTable:
    """Read a table file, checking its format, version and contents.

    Raises
    ------
    PanomapError
        Naming the file, when it is missing, not a table, corrupt or
        truncated, of another version, or its entries disagree with its model.
    """
    path = Path(path)
    try:
        file = path.open("rb")
    except FileNotFoundError:
        raise PanomapError("no such table file", path) from None
    except OSError as exc:
        raise PanomapError(f"cannot read it ({exc.strerror or exc})", path) from None
    try:
        with file, np.load(file, allow_pickle=False) as archive:
            names = set(archive.files)
            if not {"entries", "meta"} <= names:
                raise PanomapError("not a panomap table (no entries/meta inside)", path)
            meta_text = str(archive["meta"][()])
            entries = archive["entries"]
    except PanomapError:
        raise
    except (zipfile.BadZipFile, EOFError, ValueError, OSError, KeyError, zipfile.LargeZipFile) as exc:
        raise PanomapError(
            f"not a readable panomap table: corrupt or truncated ({exc.__class__.__name__})", path
        ) from None
    try:
        meta = json.loads(meta_text)
    except json.JSONDecodeError:
        raise PanomapError("the table's metadata is not valid JSON (corrupt)", path) from None
    if not isinstance(meta, dict) or meta.get("format") != TABLE_FORMAT:
        raise PanomapError("not a panomap table (wrong format tag)", path)
    if meta.get("version") != TABLE_VERSION:
        raise PanomapError(
            f"table format version {meta.get('version')!r}; this panomap reads version {TABLE_VERSION}", path
        )
    try:
        return _table_from(meta, entries)
    except PanomapError as exc:
        raise PanomapError(exc.detail, path) from None


def _table_from(meta: dict[str, Any], entries: NDArray[Any]) -> PanoMappingTable:
    try:
        m, n = (int(x) for x in meta["size"])
        if entries.dtype != np.float32 or entries.shape != (m, n, 2):
            raise PanomapError(
                f"entries have shape {entries.shape} {entries.dtype}, metadata says ({m}, {n}, 2) float32"
            )
        if meta.get("entries_sha256") != _digest(entries):
            raise PanomapError("the entries do not match their checksum (corrupt)")
        model = CameraModel.from_dict(meta["model"])
        rho_s, rho_e = (float(x) for x in meta["elevation_range_rad"])
        image_size = meta["image_size"]
        table = PanoMappingTable(
            entries=entries,
            elevation_range=(rho_s, rho_e),
            model=model,
            camera_position=tuple(float(x) for x in meta["camera_position"]),  # type: ignore[arg-type]
            image_size=None if image_size is None else (int(image_size[0]), int(image_size[1])),
            cutoff_radius=float(meta["cutoff_radius_px"]),
            outer_radius=float(meta["outer_radius_px"]),
            info=dict(meta.get("info") or {}),
        )
    except PanomapError:
        raise
    except (KeyError, TypeError, ValueError) as exc:
        raise PanomapError(
            f"the table's metadata is incomplete or malformed ({exc.__class__.__name__}: {exc})"
        ) from None
    if not _entries_match_model(entries, table.model, table.elevation_range):
        raise PanomapError("the entries disagree with the table's own model (corrupt)")
    return table


def _entries_match_model(
    entries: NDArray[np.float32], model: CameraModel, elevation_range: tuple[float, float], block: int = 256
) -> bool:
    """True when every entry is finite and within ENTRY_TOLERANCE_PX of :func:`fill_entries`'s.

    Compared ``block`` azimuths at a time, so that the check needs a few
    megabytes of scratch memory rather than several copies of the table.
    """
    m, n = entries.shape[:2]
    for start in range(0, m, block):
        rows = slice(start, start + block)
        difference = np.abs(fill_entries(model, (m, n), elevation_range, rows) - entries[rows])
        if not float(difference.max()) <= ENTRY_TOLERANCE_PX:  # (NaN fails too)
            return False
    return True
