"""The rig file: one ``.npz`` (a zip) holding ``rig.json`` and each camera's table file, ``cam0.npz``...

``rig.json`` is JSON: ``format = "panomap-rig"``, ``version``, the cameras' ``names`` (in the rig's order, each
stored as ``camK.npz``, K its index), the ``offsets`` of their pictures in one frame (or null) and the rig's
``info``. Each table is a whole table file (:mod:`panomap.table.file`): loading a rig checks each as
:func:`panomap.load_table` checks a table, and names the camera and the rig file where one is wrong.
"""

from __future__ import annotations

import io
import json
import os
import zipfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any, BinaryIO

from .. import inputs
from ..errors import PanomapError
from ..files import input_file, write_with
from ..table.file import read_table, table_writer
from ..table.table import PanoMappingTable
from .rig import MAX_CAMERAS, CameraRig

RIG_FORMAT = "panomap-rig"
RIG_VERSION = 1
# rig.json is at most this long (bytes); a camera's table file at most this (bytes: a table's limits).
MAX_RIG_JSON = 1 << 20
MAX_TABLE_BYTES = 1 << 31


def is_rig_file(path: str | Path) -> bool:
    """Whether ``path`` is a rig file (a zip holding ``rig.json``); False for a table file or anything else (a FIFO,
    a folder or a missing file too: the caller's own checks then name them, and nothing blocks on a pipe)."""
    if not Path(path).is_file():
        return False
    try:
        with zipfile.ZipFile(Path(path)) as archive:
            return "rig.json" in archive.namelist()
    except (zipfile.BadZipFile, OSError, ValueError):
        return False


def rig_index(path: str | Path) -> tuple[tuple[str, ...], tuple[tuple[int, int], ...] | None]:
    """The cameras' names and the offsets of their pictures in one frame (None: each its own picture) of the rig
    file ``path``, from its ``rig.json`` alone (its tables not read: ``panomap batch`` finding its inputs)."""
    path = input_file(path, missing="no such rig file")
    try:
        with zipfile.ZipFile(path) as archive:
            meta = _index(archive)
    except PanomapError as exc:
        raise PanomapError(exc.detail, path) from None
    except (zipfile.BadZipFile, OSError, EOFError) as exc:
        raise PanomapError(f"not a readable rig file ({exc.__class__.__name__})", path) from None
    offsets = meta["offsets"]
    return tuple(meta["names"]), None if offsets is None else tuple((int(x), int(y)) for x, y in offsets)


def save_rig(rig: CameraRig, path: str | Path) -> None:
    """Write ``rig`` to ``path`` (whole or not at all): ``rig.json`` and each camera's table file.

    Parameters
    ----------
    rig : CameraRig
        The rig; each table is held to :func:`panomap.save_table`'s checks.
    path : str or path
        The file to write (``.npz``).
    """
    inputs.instance(rig, CameraRig, "the rig", " (one camera's table: panomap.save_table)")
    meta = {
        "format": RIG_FORMAT,
        "version": RIG_VERSION,
        "names": list(rig.names),
        "offsets": None if rig.offsets is None else [list(offset) for offset in rig.offsets],
        "info": rig.info,
    }
    text = json.dumps(meta, indent=1, allow_nan=False)
    parts = []
    for name, table in zip(rig.names, rig.tables, strict=True):
        try:
            parts.append(table_writer(table, path))
        except PanomapError as exc:
            raise PanomapError(f"camera {name}: {exc.detail}", path) from None

    def writer(handle: BinaryIO) -> None:
        with zipfile.ZipFile(handle, "w", zipfile.ZIP_STORED) as archive:
            archive.writestr("rig.json", text)
            for k, part in enumerate(parts):
                buffer = io.BytesIO()
                part(buffer)
                archive.writestr(f"cam{k}.npz", buffer.getvalue())

    write_with(path, writer)


def load_rig(path: str | Path) -> CameraRig:
    """Read a rig file, checking its index and each camera's table as :func:`panomap.load_table` does.

    Parameters
    ----------
    path : str or path
        A rig file written by :func:`save_rig` (``panomap import`` of a camchain of several cameras).

    Raises
    ------
    PanomapError
        Naming the file (and the camera), where it is missing, not a rig, of another version, or a table in it
        is not one panomap loads.
    """
    path = input_file(path, missing="no such rig file")
    try:
        with zipfile.ZipFile(path) as archive:
            meta = _index(archive)
            for k, name in enumerate(meta["names"]):
                member = f"cam{k}.npz"
                if member not in archive.namelist():
                    raise PanomapError(f"camera {name}'s table ({member}) is missing")
                if archive.getinfo(member).file_size > MAX_TABLE_BYTES:
                    raise PanomapError(f"camera {name}'s table is larger than any table ({member})")

            def camera(k: int) -> PanoMappingTable:
                # (read in memory, not through a temporary file: 40% less time for two 1920 x 1920 lenses; each
                # thread through its own handle on the file)
                with zipfile.ZipFile(path) as own, io.BytesIO(own.read(f"cam{k}.npz")) as file:
                    try:
                        return read_table(file)
                    except PanomapError as exc:
                        raise PanomapError(f"camera {meta['names'][k]}: {exc.detail}") from None

            # The cameras side by side (their zip CRCs and SHA-256 checksums let go of the GIL); the first camera
            # in order that fails is named.
            count = len(meta["names"])
            with ThreadPoolExecutor(max(1, min(count, os.cpu_count() or 1)), thread_name_prefix="panomap-rig") as pool:
                tables = list(pool.map(camera, range(count)))
    except PanomapError as exc:
        raise PanomapError(exc.detail, path) from None
    except (zipfile.BadZipFile, OSError, EOFError) as exc:
        raise PanomapError(f"not a readable rig file ({exc.__class__.__name__})", path) from None
    try:
        return CameraRig(tuple(tables), tuple(meta["names"]), meta["offsets"], meta["info"])
    except (PanomapError, TypeError, ValueError) as exc:
        raise PanomapError(f"the rig is malformed ({exc})", path) from None


def _index(archive: zipfile.ZipFile) -> dict[str, Any]:
    """``rig.json``, checked: format, version, names, offsets, info."""
    if "rig.json" not in archive.namelist():
        raise PanomapError("not a panomap rig (no rig.json inside)")
    if archive.getinfo("rig.json").file_size > MAX_RIG_JSON:
        raise PanomapError("its rig.json is larger than any rig's")
    try:
        with io.TextIOWrapper(archive.open("rig.json"), encoding="utf-8") as member:  # (closed: the zip's file too)
            meta = json.load(member)
    except (json.JSONDecodeError, UnicodeDecodeError, RecursionError):
        raise PanomapError("its rig.json is not valid JSON (corrupt)") from None
    if not isinstance(meta, dict) or meta.get("format") != RIG_FORMAT:
        raise PanomapError("not a panomap rig (rig.json names another format)")
    if meta.get("version") != RIG_VERSION:
        raise PanomapError(f"rig format version {meta.get('version')!r}: this panomap reads version {RIG_VERSION}")
    names = meta.get("names")
    if not isinstance(names, list) or not 1 <= len(names) <= MAX_CAMERAS or not all(isinstance(n, str) for n in names):
        raise PanomapError(f"rig.json's names must be a list of 1 to {MAX_CAMERAS} texts")
    offsets = meta.get("offsets")
    if offsets is not None and not (
        isinstance(offsets, list)
        and len(offsets) == len(names)
        and all(
            isinstance(o, list) and len(o) == 2 and all(isinstance(x, int) and 0 <= x < 1 << 20 for x in o)
            for o in offsets
        )
    ):
        raise PanomapError("rig.json's offsets must be one pair of pixel counts per camera")
    if not isinstance(meta.get("info", {}), dict):
        raise PanomapError("rig.json's info must be an object")
    meta.setdefault("info", {})
    meta.setdefault("offsets", None)  # (none written: each camera takes its own picture)
    return meta
