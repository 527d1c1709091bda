"""The table file: a NumPy ``.npz`` holding ``entries`` and ``meta``.

``meta`` is JSON text with ``format = "panomap-table"``, ``version``, the
model, the elevation range, radii, image size, camera position, the table's
``info`` (where the centre and radii came from, the landmarks and the fit
report), the SHA-256 of ``entries`` and (since version 2) the SHA-256 of the
metadata itself. Version 3 adds a tilted camera's rotation (in the model) and
its own elevation range; versions 1 and 2 (level cameras only) still load. Version 4 adds a camera
without a single viewpoint, version 5 the image terms beyond the radial law (aspect, skew, decentering).
Loading checks all of it, in an order that bounds memory and time before the
work starts:

1. the arrays' declared shapes and types, from their headers, against the
   limits (nothing is read yet);
2. every metadata field against its schema (:class:`TableMetadata`), then the
   metadata's checksum (versions 2 and 3; version 1 files, whose checksum covers
   only the entries, still load);
3. the entries: their shape against the metadata, their checksum, and that
   they are what the model gives.
"""

from __future__ import annotations

import hashlib
import json
import math
import zipfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

import numpy as np
from numpy.typing import NDArray

from .. import inputs
from ..camera.model import CameraModel
from ..errors import PanomapError
from ..files import input_file, write_with
from ..values import MAX_ABS
from .sampling import MAX_TABLE_SIDE
from .table import MAX_TABLE_ENTRIES, TABLE_FORMAT, TERMS_VERSION, PanoMappingTable, fill_entries

READ_VERSIONS = (1, 2, 3, 4, 5)
# Version 3 added the camera's rotation (a tilted camera) to the model; older files hold level cameras.
ROTATION_VERSION = 3
# Version 4 added the ray origins of a camera without a single viewpoint (``model["viewpoint"]``).
VIEWPOINT_VERSION = 4
# Version 5 added the image terms beyond the radial law (``model["terms"]``, :mod:`panomap.camera.image_terms`).
# Entries are float32: about 1e-4 px at radii of 2000 px. A loaded table whose
# entries stray further than this from its own model is corrupt.
ENTRY_TOLERANCE_PX = 1e-2
# The metadata's JSON text, at most (characters): a fit report of thousands of landmarks fits.
MAX_METADATA_CHARS = 1 << 22
# An image side a table can be for, at most (px).
MAX_IMAGE_SIDE = 1 << 20
_FIELDS = {
    "format",
    "version",
    "size",
    "elevation_range_rad",
    "model",
    "camera_position",
    "image_size",
    "cutoff_radius_px",
    "outer_radius_px",
    "info",
    "entries_sha256",
    "metadata_sha256",
    "camera_elevation_range_rad",
}


# Bytes of one entry in a table file (azimuth and elevation's (u, v), float32): a table of M x N entries takes
# at least M * N * ENTRY_BYTES on disk.
ENTRY_BYTES = 8


def save_table(table: PanoMappingTable, path: str | Path) -> None:
    """Write the table to ``path`` (an ``.npz``), through a temporary file.

    The file is first held to the checks :func:`load_table` makes of its metadata and its arrays' sizes
    (the image size within :data:`MAX_IMAGE_SIDE`, the radii, the table limits...): a table that no
    command could load is refused here, naming ``path``, and nothing is written.

    Parameters
    ----------
    table : PanoMappingTable
        The table; its entries, model and ``info`` are written with checksums of both.
    path : str or path
        The file to write (whole or not at all).

    Raises
    ------
    TypeError
        ``table`` no :class:`PanoMappingTable`; its ``info`` holding what JSON cannot (an object, a set, a
        NumPy scalar), naming where.
    PanomapError
        ``info`` holding NaN or an infinity, a table no command could load, a file that cannot be written.
    """
    write_with(path, table_writer(table, path))


def table_writer(table: PanoMappingTable, path: str | Path) -> Callable[[IO[bytes]], None]:
    """What :func:`save_table` writes, checked as it checks it (``path`` named in its errors), as a function that
    writes the archive to an open binary file (a rig file's part, :mod:`panomap.rig.file`)."""
    inputs.instance(table, PanoMappingTable, "the table", " (panomap.load_table reads a file)")
    inputs.info(table.info, "the table's info")
    meta = table.metadata() | {"entries_sha256": _digest(table.entries)}
    meta["metadata_sha256"] = metadata_digest(meta)
    text = json.dumps(meta, indent=1, allow_nan=False)
    _check_loadable(text, table.entries, path)

    def writer(handle: Any) -> None:
        np.savez(handle, entries=table.entries, meta=np.array(text))

    return writer


def _check_loadable(text: str, entries: NDArray[np.float32], path: str | Path) -> None:
    """Refuse to write a table :func:`load_table` would refuse: its metadata ``text`` and the declared
    shapes of ``entries`` and of the metadata, checked as a load checks them."""
    try:
        _check_declared(
            (tuple(entries.shape), np.dtype(entries.dtype).newbyteorder("<")),
            ((), np.dtype(f"<U{max(len(text), 1)}")),
        )
        TableMetadata.from_dict(json.loads(text))
    except PanomapError as exc:
        raise PanomapError(f"not written: no command could load this table ({exc.detail})", path) from None


def _digest(entries: NDArray[np.float32]) -> str:
    return hashlib.sha256(np.ascontiguousarray(entries, dtype="<f4").data).hexdigest()


def metadata_digest(meta: dict[str, Any]) -> str:
    """SHA-256 of the metadata (all but ``metadata_sha256``) as canonical JSON: sorted keys, no spaces."""
    body = {key: value for key, value in meta.items() if key != "metadata_sha256"}
    text = json.dumps(body, sort_keys=True, separators=(",", ":"), allow_nan=False, ensure_ascii=True)
    return hashlib.sha256(text.encode("ascii")).hexdigest()


# ----------------------------------------------------------------------------- the metadata's schema


def _malformed(detail: str) -> PanomapError:
    return PanomapError(f"the table's metadata is malformed ({detail})")


def _numbers(meta: dict[str, Any], key: str, count: int, integer: bool = False) -> tuple[Any, ...]:
    """``meta[key]``: a list of ``count`` finite numbers (integers if ``integer``)."""
    value = meta[key]
    kinds = (int,) if integer else (int, float)
    if (
        not isinstance(value, list)
        or len(value) != count
        or not all(isinstance(x, kinds) and not isinstance(x, bool) for x in value)
        or not all(math.isfinite(x) for x in value)
    ):
        what = "integers" if integer else "finite numbers"
        raise _malformed(f"{key} is {_shown(value)}, not a list of {count} {what}")
    return tuple(int(x) for x in value) if integer else tuple(float(x) for x in value)


def _number(meta: dict[str, Any], key: str) -> float:
    value = meta[key]
    if not isinstance(value, int | float) or isinstance(value, bool) or not math.isfinite(value):
        raise _malformed(f"{key} is {_shown(value)}, not a finite number")
    return float(value)


def _check_all_numbers(meta: dict[str, Any]) -> None:
    """Refuse a number anywhere in the metadata (``info`` included) that is no finite float: a 400-digit
    integer, which JSON reads but no float holds (an ``OverflowError`` deep in a command), or an infinity
    (``1e400``); the field named as ``model.centre[0]``. (save_table writes neither.)"""
    stack: list[tuple[str, Any]] = [("", meta)]
    while stack:
        where, value = stack.pop()
        if isinstance(value, dict):
            stack.extend((f"{where}.{key}" if where else str(key), item) for key, item in value.items())
        elif isinstance(value, list):
            stack.extend((f"{where}[{index}]", item) for index, item in enumerate(value))
        elif isinstance(value, int | float) and not isinstance(value, bool):
            try:
                finite = math.isfinite(value)
            except OverflowError:  # an integer beyond the floats' range
                finite = False
            if not finite:
                raise _malformed(f"{where} is {_shown(value)}, not a finite number")


def _within(values: tuple[float, ...], key: str, unit: str) -> None:
    """Refuse a geometric field beyond :data:`~panomap.values.MAX_ABS` in size: no camera, room or image is
    that large, and the views' arithmetic on it overflows (NumPy warnings, an empty view)."""
    if any(abs(x) > MAX_ABS for x in values):
        shown = ", ".join(f"{x:g}" for x in values)
        raise _malformed(f"{key} is {shown}: beyond {MAX_ABS:g} {unit} in size")


def _shown(value: Any) -> str:
    text = json.dumps(value, allow_nan=True) if not isinstance(value, float) else repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _check_info(info: Any) -> dict[str, Any]:
    """``info``'s structure where the table's users rely on it (the fit report's own fields
    are checked by :class:`panomap.calibrate.core.report.FitReport` when it is read)."""
    if info is None:
        return {}
    if not isinstance(info, dict):
        raise _malformed(f"info is {_shown(info)}, not an object")
    sources = info.get("sources", {})
    if not isinstance(sources, dict) or not all(isinstance(v, str) for v in sources.values()):
        raise _malformed(f"info.sources is {_shown(sources)}, not an object of texts")
    warnings = info.get("warnings", [])
    if not isinstance(warnings, list) or not all(isinstance(w, str) for w in warnings):
        raise _malformed(f"info.warnings is {_shown(warnings)}, not a list of texts")
    for key in ("fit", "image_circles"):
        if info.get(key) is not None and not isinstance(info[key], dict):
            raise _malformed(f"info.{key} is {_shown(info[key])}, not an object")
    return dict(info)


@dataclass(frozen=True)
class TableMetadata:
    """A table file's metadata, every field checked (:meth:`from_dict`); ``model`` as stored."""

    version: int
    size: tuple[int, int]
    elevation_range: tuple[float, float]
    model: CameraModel
    camera_position: tuple[float, float, float]
    image_size: tuple[int, int] | None
    cutoff_radius: float
    outer_radius: float
    info: dict[str, Any]
    entries_sha256: str
    camera_elevation_range: tuple[float, float] | None = None

    @classmethod
    def from_dict(cls, meta: Any) -> TableMetadata:
        """Check the metadata as a whole: format, version, every field's type and range, the checksum.

        Raises
        ------
        PanomapError
            With one line saying which field is wrong and how.
        """
        if not isinstance(meta, dict) or meta.get("format") != TABLE_FORMAT:
            raise PanomapError("not a panomap table (wrong format tag)")
        version = meta.get("version")
        if type(version) is not int or version not in READ_VERSIONS:  # (not true, 2.0 or "2", which compare equal)
            raise PanomapError(
                f"table format version {version!r}; this panomap reads versions "
                + ", ".join(map(str, READ_VERSIONS[:-1]))
                + f" and {READ_VERSIONS[-1]}"
            )
        required = _FIELDS - {"metadata_sha256", "info", "camera_elevation_range_rad"} | (
            {"metadata_sha256"} if version >= 2 else set()
        )
        missing, unknown = sorted(required - set(meta)), sorted(set(meta) - _FIELDS)
        if missing or unknown:
            raise _malformed(", ".join([*(f"no {k}" for k in missing), *(f"unknown field {k}" for k in unknown)]))
        _check_all_numbers(meta)
        m, n = _numbers(meta, "size", 2, integer=True)
        if not (2 <= m <= MAX_TABLE_SIDE and 2 <= n <= MAX_TABLE_SIDE) or m * n > MAX_TABLE_ENTRIES:
            raise _malformed(f"size {m}x{n}: 2 to {MAX_TABLE_SIDE} a side, {MAX_TABLE_ENTRIES:,} entries at most")
        elevation_range = _numbers(meta, "elevation_range_rad", 2)
        camera_position = _numbers(meta, "camera_position", 3)
        _within(camera_position, "camera_position", "world units")
        image_size = None if meta["image_size"] is None else _numbers(meta, "image_size", 2, integer=True)
        if image_size is not None and not all(1 <= side <= MAX_IMAGE_SIDE for side in image_size):
            raise _malformed(f"image_size {image_size[0]}x{image_size[1]} is not a size of an image")
        cutoff, outer = _number(meta, "cutoff_radius_px"), _number(meta, "outer_radius_px")
        _within((cutoff, outer), "the radii (cutoff_radius_px, outer_radius_px)", "px")
        if not 0 <= cutoff < outer:
            raise _malformed(f"the radii must be 0 <= cutoff_radius_px < outer_radius_px, not {cutoff:g}, {outer:g}")
        if not isinstance(meta["model"], dict):
            raise _malformed(f"model is {_shown(meta['model'])}, not an object")
        if version < ROTATION_VERSION and "rotation" in meta["model"]:
            raise _malformed(f"a version {version} table holds no camera rotation (version {ROTATION_VERSION} does)")
        if version < VIEWPOINT_VERSION and "viewpoint" in meta["model"]:
            raise _malformed(f"a version {version} table holds no viewpoint (version {VIEWPOINT_VERSION} does)")
        if version < TERMS_VERSION and "terms" in meta["model"]:
            raise _malformed(f"a version {version} table holds no image terms (version {TERMS_VERSION} does)")
        try:
            model = CameraModel.from_dict(meta["model"])
        except PanomapError as exc:
            raise _malformed(exc.detail) from None
        _within(model.centre, "model.centre", "px")
        camera_range = None
        if (model.rotation is None) != ("camera_elevation_range_rad" not in meta):
            raise _malformed("camera_elevation_range_rad is there exactly when the model has a rotation")
        if model.rotation is not None:
            camera_range = _numbers(meta, "camera_elevation_range_rad", 2)
            if not -math.pi / 2 <= camera_range[0] < camera_range[1] <= math.pi / 2:
                raise _malformed(f"camera_elevation_range_rad {camera_range} is not an elevation range")
        if image_size is not None:
            (u0, v0), (width, height) = model.centre, image_size
            farthest = max(math.hypot(u - u0, v - v0) for u in (-0.5, width - 0.5) for v in (-0.5, height - 0.5))
            if cutoff >= farthest:
                raise _malformed(f"cutoff_radius_px {cutoff:g} leaves no pixel of a {width} x {height} image visible")
        info = _check_info(meta.get("info"))
        for key in ("entries_sha256", "metadata_sha256"):
            value = meta.get(key, "0" * 64)
            if not isinstance(value, str) or len(value) != 64 or set(value) - set("0123456789abcdef"):
                raise _malformed(f"{key} is {_shown(value)}, not a SHA-256 in hex")
        if version >= 2 and meta["metadata_sha256"] != metadata_digest(meta):
            raise PanomapError("the metadata does not match its checksum (corrupt or edited)")
        return cls(
            version,
            (m, n),
            (elevation_range[0], elevation_range[1]),
            model,
            (camera_position[0], camera_position[1], camera_position[2]),
            None if image_size is None else (image_size[0], image_size[1]),
            cutoff,
            outer,
            info,
            meta["entries_sha256"],
            None if camera_range is None else (camera_range[0], camera_range[1]),
        )


# ----------------------------------------------------------------------------- loading


def _array_header(archive: Any, name: str) -> tuple[tuple[int, ...], np.dtype[Any]]:
    """The shape and dtype an ``.npz`` member declares, read from its header without reading the array."""
    member: IO[bytes]
    with archive.zip.open(f"{name}.npy") as member:
        version = np.lib.format.read_magic(member)
        if version == (1, 0):
            shape, _, dtype = np.lib.format.read_array_header_1_0(member)
        elif version == (2, 0):
            shape, _, dtype = np.lib.format.read_array_header_2_0(member)
        else:
            raise ValueError(f"array format version {version}")
    return tuple(int(x) for x in shape), dtype


def _check_declared(
    entries: tuple[tuple[int, ...], np.dtype[Any]], meta: tuple[tuple[int, ...], np.dtype[Any]]
) -> None:
    """Refuse arrays whose declared shapes or types are beyond the limits, before reading them."""
    shape, dtype = entries
    if dtype != np.dtype("<f4") or len(shape) != 3 or shape[2] != 2:
        raise PanomapError(f"entries are declared {shape} {dtype}, not (M, N, 2) float32 (corrupt)")
    m, n = shape[:2]
    if max(m, n) > MAX_TABLE_SIDE or m * n > MAX_TABLE_ENTRIES:
        raise PanomapError(
            f"the file declares a {m} x {n} table: more than the limits ({MAX_TABLE_SIDE} a side, "
            f"{MAX_TABLE_ENTRIES:,} entries); not read"
        )
    shape, dtype = meta
    if shape != () or dtype.kind != "U" or dtype.itemsize // 4 > MAX_METADATA_CHARS:
        raise PanomapError(
            f"the metadata is declared {shape} {dtype}, not a text of at most {MAX_METADATA_CHARS:,} characters"
        )


def is_table_file(path: str | Path) -> bool:
    """Whether ``path`` is a table file (a zip holding ``entries`` and ``meta``, as :func:`save_table` writes),
    from its members' names alone; False for a rig file or anything else (a missing file, a folder too)."""
    if not Path(path).is_file():
        return False
    try:
        with zipfile.ZipFile(Path(path)) as archive:
            return {"entries.npy", "meta.npy"} <= set(archive.namelist())
    except (zipfile.BadZipFile, OSError, ValueError):
        return False


def load_table(path: str | Path) -> PanoMappingTable:
    """Read a table file, checking its format, version and contents.

    Parameters
    ----------
    path : str or path
        A table file written by :func:`save_table` (``panomap fit``, ``panomap import``, the learn page).

    Returns
    -------
    PanoMappingTable

    Raises
    ------
    PanomapError
        Naming the file, when it is missing, not a table, corrupt or
        truncated, of another version, declares arrays beyond the limits, has
        a malformed or edited metadata field, or its entries disagree with
        its checksum or its model.
    """
    path = input_file(path, missing="no such table file")  # (a FIFO would block the read)
    try:
        file = path.open("rb")
    except FileNotFoundError:
        raise PanomapError("no such table file", path) from None
    except OSError as exc:
        raise PanomapError(f"cannot read it ({exc.strerror or exc})", path) from None
    try:
        with file:
            return read_table(file)
    except PanomapError as exc:
        raise PanomapError(exc.detail, path) from None


def read_table(file: IO[bytes]) -> PanoMappingTable:
    """A table from an open table file (seekable, binary), checked as :func:`load_table` checks it; errors say
    what is wrong without naming a file (the caller names it: a file, or a camera of a rig file)."""
    head = file.read(4)
    file.seek(0)
    if not head.startswith(b"PK"):  # (every .npz is a zip; an empty file, a picture, a CSV ... is not)
        what = "an empty file" if not head else "not a .npz archive"
        raise PanomapError(f"not a panomap table ({what}; panomap import or panomap fit makes one)")
    try:
        with np.load(file, allow_pickle=False) as archive:
            if not isinstance(archive, np.lib.npyio.NpzFile) or not {"entries", "meta"} <= set(archive.files):
                if (
                    isinstance(archive, np.lib.npyio.NpzFile)
                    and archive.zip is not None
                    and "rig.json" in archive.zip.namelist()
                ):
                    raise PanomapError("a rig of several cameras, not one camera's table: give one of its tables")
                raise PanomapError("not a panomap table (no entries/meta inside)")
            _check_declared(_array_header(archive, "entries"), _array_header(archive, "meta"))
            try:
                meta = TableMetadata.from_dict(json.loads(str(archive["meta"][()])))
            except (json.JSONDecodeError, RecursionError):
                raise PanomapError("the table's metadata is not valid JSON (corrupt)") from None
            if (meta.size[0], meta.size[1], 2) != _array_header(archive, "entries")[0]:
                shape = _array_header(archive, "entries")[0]
                raise PanomapError(
                    f"entries have shape {shape} float32, metadata says ({meta.size[0]}, {meta.size[1]}, 2) float32"
                )
            entries = archive["entries"]
    except PanomapError:
        raise
    except (zipfile.BadZipFile, EOFError, ValueError, OSError, KeyError, zipfile.LargeZipFile) as exc:
        raise PanomapError(f"not a readable panomap table: corrupt or truncated ({exc.__class__.__name__})") from None
    return _table_from(meta, entries)


def _table_from(meta: TableMetadata, entries: NDArray[Any]) -> PanoMappingTable:
    if meta.entries_sha256 != _digest(entries):
        raise PanomapError("the entries do not match their checksum (corrupt)")
    table = PanoMappingTable(
        entries=entries,
        elevation_range=meta.elevation_range,
        model=meta.model,
        camera_position=meta.camera_position,
        image_size=meta.image_size,
        cutoff_radius=meta.cutoff_radius,
        outer_radius=meta.outer_radius,
        info=meta.info,
        camera_elevation_range=meta.camera_elevation_range,
    )
    # An imported table's entries come from its calibration's model (info["import"]), not from its radial
    # approximation: the checksum alone guards them.
    if table.entries_from_model and not _entries_match_model(
        entries, table.model, table.elevation_range, table.camera_elevation_range
    ):
        raise PanomapError("the entries disagree with the table's own model (corrupt)")
    return table


def _entries_match_model(
    entries: NDArray[np.float32],
    model: CameraModel,
    elevation_range: tuple[float, float],
    camera_range: tuple[float, float] | None = None,
    block: int = 256,
) -> bool:
    """True when every entry is within ENTRY_TOLERANCE_PX of :func:`fill_entries`'s: finite, or NaN exactly
    where a tilted camera does not see the entry's ray.

    Compared ``block`` azimuths at a time, so that the check needs a few
    megabytes of scratch memory rather than several copies of the table.
    """
    m, n = entries.shape[:2]
    for start in range(0, m, block):
        rows = slice(start, start + block)
        expected = fill_entries(model, (m, n), elevation_range, rows, camera_range)
        difference = np.abs(expected - entries[rows])
        if camera_range is not None:
            unseen = np.isnan(expected)
            if not np.array_equal(unseen, np.isnan(entries[rows])):
                return False
            difference[unseen] = 0.0
        if not float(difference.max()) <= ENTRY_TOLERANCE_PX:  # (NaN fails too)
            return False
    return True
