"""Landmark point pairs (paper 2.1): world points and their pixels, and their files.

Files:

- CSV: a header with at least ``u,v,X,Y,Z`` (any order, any case, an
  optional ``name`` column), one landmark per row; world coordinates in world
  units, pixels in the conventions' (u, v) (centre of the top-left pixel at 0, 0).
  Fields are separated by commas or, where the header holds no comma, by
  semicolons or tabs (what spreadsheets write where the decimal mark is a
  comma; such files may then write ``1,5`` for 1.5). Rows are counted as the
  file's lines, blank lines included.
  A name that a spreadsheet would take for a formula (one starting with ``=``,
  ``+``, ``-``, ``@``, a tab or a carriage return) is written with a ``'`` before
  it, as OWASP advises against CSV injection, and so is one that starts with
  ``'``; reading drops that one ``'`` again, so names round-trip.
- JSON: ``{"camera": [X0, Y0, Z0], "landmarks": [{"name": ..., "u": ...,
  "v": ..., "X": ..., "Y": ..., "Z": ...}, ...]}``; ``camera`` is optional.
"""

from __future__ import annotations

import csv
import io
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ... import inputs
from ...errors import PanomapError
from ...files import file_path, read_text
from ...geometry import FloatArray
from ...values import NotFinite, TooLarge, finite_number

COLUMNS = ("u", "v", "X", "Y", "Z")
MIN_LANDMARKS = 5
# First characters of a CSV cell that spreadsheets run as a formula, and the escape itself.
FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r", "'")
# Field separators a CSV may use, in the order they are looked for in its header.
DELIMITERS = (",", ";", "\t")


def escape_csv_name(name: str) -> str:
    """``name`` made safe to open in a spreadsheet: a ``'`` before a formula's first character."""
    return "'" + name if name.startswith(FORMULA_STARTS) else name


def unescape_csv_name(cell: str) -> str:
    """The name :func:`escape_csv_name` wrote into ``cell``."""
    return cell[1:] if cell.startswith("'") and cell[1:].startswith(FORMULA_STARTS) else cell


@dataclass(frozen=True)
class Landmarks:
    """Landmark point pairs.

    Parameters
    ----------
    pixels : (n, 2) ndarray
        Image points (u, v), px.
    world : (n, 3) ndarray
        World points (X, Y, Z), world units.
    names : tuple of str
        One name per landmark (``"L1"``, ... when the file has none).
    camera : (3,) tuple of float, optional
        Camera position O_m = (X0, Y0, Z0) when the file gives one.
    """

    pixels: FloatArray
    world: FloatArray
    names: tuple[str, ...]
    camera: tuple[float, float, float] | None = None

    def __post_init__(self) -> None:
        if isinstance(self.names, str | bytes):
            raise TypeError(f"landmarks: names must be a sequence of names, one per landmark, not {self.names!r:.40}")
        pixels = inputs.points(self.pixels, 2, "landmarks: the pixels").reshape(-1, 2).copy()
        world = inputs.points(self.world, 3, "landmarks: the world points").reshape(-1, 3).copy()
        if len(pixels) != len(world) or len(self.names) != len(pixels):
            raise PanomapError("landmarks: pixels, world points and names differ in count")
        for label, values in (("pixel", pixels), ("world point", world)):
            bad = np.flatnonzero(~np.all(np.isfinite(values), axis=1))
            if bad.size:
                raise PanomapError(f"landmark {self.names[bad[0]]!r} has a non-finite {label}")
        if self.camera is not None and not all(math.isfinite(c) for c in self.camera):
            raise PanomapError("the camera position is not finite")
        pixels.setflags(write=False)
        world.setflags(write=False)
        object.__setattr__(self, "pixels", pixels)
        object.__setattr__(self, "world", world)
        object.__setattr__(self, "names", tuple(str(n) for n in self.names))

    def __len__(self) -> int:
        return len(self.names)

    def to_records(self) -> list[dict[str, Any]]:
        """One dict per landmark: name, u, v, X, Y, Z."""
        return [
            {"name": n, "u": p[0], "v": p[1], "X": w[0], "Y": w[1], "Z": w[2]}
            for n, p, w in zip(self.names, self.pixels.tolist(), self.world.tolist(), strict=True)
        ]


def read_landmarks(path: str | Path) -> Landmarks:
    """Read landmarks from a CSV or JSON file (chosen by the ``.json`` suffix).

    Parameters
    ----------
    path : str or path
        A CSV of ``u,v,X,Y,Z[,name]`` rows (comma-, semicolon- or tab-separated, a header optional), or a
        JSON file of landmarks (which may also hold the camera position).

    Returns
    -------
    Landmarks

    Raises
    ------
    PanomapError
        Naming the file and, where it helps, the row, for a missing or
        unreadable file, missing columns, a value that is not a finite number.
    """
    path = file_path(path)
    text = read_text(path)
    try:
        if path.suffix.lower() == ".json":
            return _from_json(text)
        return _from_csv(text)
    except PanomapError as exc:
        raise PanomapError(exc.detail, path) from None


def _number(value: Any, what: str) -> float:
    if isinstance(value, bool):  # (JSON true and false are not numbers, though Python counts them as 1 and 0)
        raise PanomapError(f"{what} is not a number: {json.dumps(value)}")
    try:
        return finite_number(value)
    except TooLarge as exc:
        raise PanomapError(f"{what} is too large: {value!r} (at most {exc.limit:g} in size)") from None
    except NotFinite as exc:
        raise PanomapError(f"{what} is not {'finite' if exc.number else 'a number'}: {value!r}") from None


def _csv_rows(text: str) -> tuple[list[tuple[int, list[str]]], str]:
    """The CSV's non-blank rows, each with its line number in the file (the header's is the first), and the
    separator of its fields: a comma, or where the header holds none a semicolon or a tab."""
    lines = [(number, line) for number, line in enumerate(text.splitlines(), start=1) if line.strip()]
    header = lines[0][1] if lines else ""
    delimiter = next((d for d in DELIMITERS if d in header), ",")
    rows = csv.reader((line for _, line in lines), delimiter=delimiter)
    return [(number, row) for (number, _), row in zip(lines, rows, strict=True)], delimiter


def _cell_number(cell: str, delimiter: str, what: str) -> float:
    """A CSV cell's number; where the fields are not comma-separated, a decimal comma (``1,5``) is read too."""
    cell = cell.strip()
    if delimiter != "," and "," in cell and "." not in cell:
        cell = cell.replace(",", ".", 1)
    return _number(cell, what)


def _from_csv(text: str) -> Landmarks:
    rows, delimiter = _csv_rows(text)
    if not rows:
        raise PanomapError("the landmark CSV is empty")
    header = [h.strip() for h in rows[0][1]]
    lowered = [h.lower() for h in header]
    missing = [c for c in COLUMNS if c.lower() not in lowered]
    if missing:
        raise PanomapError(
            f"the CSV lacks the column(s) {','.join(missing)}; its header must hold u,v,X,Y,Z "
            f"(and optionally name), it holds {','.join(header) or 'nothing'}"
        )
    _check_columns_once(header, (*COLUMNS, "name"))
    index = {c: lowered.index(c.lower()) for c in COLUMNS}
    name_index = lowered.index("name") if "name" in lowered else None
    pixels, world, names = [], [], []
    unnamed: list[bool] = []
    lines: list[int] = []
    for place, (line, row) in enumerate(rows[1:], start=1):
        if len(row) < len(header):
            raise PanomapError(f"row {line} has {len(row)} fields, the header {len(header)}")
        values = [_cell_number(row[index[c]], delimiter, f"row {line}, {c}") for c in COLUMNS]
        pixels.append(values[:2])
        world.append(values[2:])
        name = unescape_csv_name(row[name_index].strip()) if name_index is not None else ""
        names.append(name or f"L{place}")
        unnamed.append(not name)
        lines.append(line)
        _check_named_once(names, unnamed, "row", lines)
    return Landmarks(np.array(pixels).reshape(-1, 2), np.array(world).reshape(-1, 3), tuple(names))


def _check_columns_once(header: list[str], columns: tuple[str, ...]) -> None:
    """Refuse a header that holds one of ``columns`` twice (in any case): which of the two is meant is a guess."""
    lowered = [h.lower() for h in header]
    for column in columns:
        places = [k + 1 for k, h in enumerate(lowered) if h == column.lower()]
        if len(places) > 1:
            raise PanomapError(
                f"the CSV's header holds {column} {len(places)} times (columns {', '.join(map(str, places))}): keep one"
            )


def _check_named_once(names: list[str], unnamed: list[bool], what: str, places: list[int]) -> None:
    """Refuse the last of ``names`` where an earlier one is the same (the report names landmarks: two of one
    name make it ambiguous). ``unnamed``: which were named for want of a name in the file; ``what`` and
    ``places``: how the file counts them (row 2, landmark 1, ...), one per name."""
    name = names[-1]
    if name in names[:-1]:
        earlier = names.index(name)
        given = [places[k] for k in (earlier, len(names) - 1) if unnamed[k]]
        why = f" ({what} {given[0]} has no name: that is the one it was given)" if given else ""
        raise PanomapError(
            f"{what}s {places[earlier]} and {places[-1]} are both named {name!r}{why}: "
            "give each landmark a name of its own"
        )


def _from_json(text: str) -> Landmarks:
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise PanomapError(f"not valid JSON ({exc})") from None
    except RecursionError:
        raise PanomapError("not valid landmarks JSON (nested too deeply)") from None
    if not isinstance(data, dict) or not isinstance(data.get("landmarks"), list):
        raise PanomapError('the JSON must be an object with a "landmarks" list')
    pixels, world, names = [], [], []
    unnamed: list[bool] = []
    for k, item in enumerate(data["landmarks"], start=1):
        if not isinstance(item, dict):
            raise PanomapError(f"landmark {k} is not an object")
        missing = [c for c in COLUMNS if c not in item]
        if missing:
            raise PanomapError(f"landmark {k} lacks {','.join(missing)}")
        values = [_number(item[c], f"landmark {k}, {c}") for c in COLUMNS]
        pixels.append(values[:2])
        world.append(values[2:])
        names.append(str(item.get("name") or f"L{k}"))
        unnamed.append(not item.get("name"))
        _check_named_once(names, unnamed, "landmark", list(range(1, k + 1)))
    camera = data.get("camera")
    position = None
    if camera is not None:
        if not isinstance(camera, list) or len(camera) != 3:
            raise PanomapError('"camera" must be a list [X0, Y0, Z0]')
        x0, y0, z0 = (_number(c, "camera") for c in camera)
        position = (x0, y0, z0)
    return Landmarks(np.array(pixels).reshape(-1, 2), np.array(world).reshape(-1, 3), tuple(names), position)


def landmarks_to_csv(landmarks: Landmarks) -> str:
    """The landmarks as CSV text with the header ``name,u,v,X,Y,Z``.

    Numbers are written with ``repr`` (they read back exactly); names are quoted
    where CSV needs it and escaped where a spreadsheet would run them
    (:func:`escape_csv_name`); :func:`read_landmarks` gives the same names back.
    """
    text = io.StringIO()
    writer = csv.writer(text, lineterminator="\n")
    writer.writerow(["name", *COLUMNS])
    for record in landmarks.to_records():
        writer.writerow([escape_csv_name(record["name"]), *(repr(float(record[c])) for c in COLUMNS)])
    return text.getvalue()


@dataclass(frozen=True)
class PointRows:
    """A points CSV as read: its header and every row's fields (to pass through), the wanted columns' values,
    and how the file writes its fields, so that an output made from it can write them alike."""

    header: list[str]
    rows: list[list[str]]
    values: FloatArray
    """(n, len(columns)): world units for X, Y, Z; px for u, v."""
    delimiter: str = ","
    decimal_comma: bool = False
    """Whether its numbers use a decimal comma (``1,5``: only in a file not separated by commas)."""

    def number(self, value: float, decimals: int) -> str:
        """``value`` written with ``decimals`` decimals and the file's decimal mark."""
        text = f"{value:.{decimals}f}"
        return text.replace(".", ",") if self.decimal_comma else text


def read_points(path: str | Path, columns: tuple[str, ...] = ("X", "Y", "Z")) -> PointRows:
    """Read numeric columns (by default world points ``X,Y,Z``) from a CSV, keeping every row.

    Parameters
    ----------
    path : str or path-like
        A CSV with a header holding at least ``columns`` (any case, any order;
        its fields separated as :func:`read_landmarks` reads them); other
        columns are kept for passing through.
    columns : tuple of str
        The columns to read as numbers, e.g. ``("u", "v")`` for pixels.

    Returns
    -------
    PointRows
        The header, the rows, the values (n, len(columns)) and the file's separator and decimal mark.

    Raises
    ------
    PanomapError
        Naming the file (and the row), for a missing or unreadable file, a
        missing column, a short row or a value that is not a finite number.
    """
    path = Path(path)
    text = read_text(path)
    numbered, delimiter = _csv_rows(text)
    wanted = ",".join(columns)
    if not numbered:
        raise PanomapError(f"the CSV is empty; it needs a header with {wanted}", path)
    header = [h.strip() for h in numbered[0][1]]
    lowered = [h.lower() for h in header]
    missing = [c for c in columns if c.lower() not in lowered]
    if missing:
        raise PanomapError(f"the CSV lacks the column(s) {','.join(missing)}; it holds {','.join(header)}", path)
    try:
        _check_columns_once(header, columns)
    except PanomapError as exc:
        raise PanomapError(exc.detail, path) from None
    index = [lowered.index(c.lower()) for c in columns]
    values = []
    for line, row in numbered[1:]:
        if len(row) < len(header):
            raise PanomapError(f"row {line} has {len(row)} fields, the header {len(header)}", path)
        try:
            values.append([_cell_number(row[i], delimiter, f"row {line}, {header[i]}") for i in index])
        except PanomapError as exc:
            raise PanomapError(exc.detail, path) from None
    rows = [row for _, row in numbered[1:]]
    decimal_comma = delimiter != "," and any("," in row[i] for row in rows for i in index)
    array = np.array(values, dtype=np.float64).reshape(-1, len(columns))
    return PointRows(header, rows, array, delimiter, decimal_comma)


def landmarks_to_json(landmarks: Landmarks) -> str:
    """The landmarks as JSON text that :func:`read_landmarks` reads, with ``camera`` when known."""
    data: dict[str, Any] = {}
    if landmarks.camera is not None:
        data["camera"] = [float(c) for c in landmarks.camera]
    data["landmarks"] = [{"name": r["name"], **{c: float(r[c]) for c in COLUMNS}} for r in landmarks.to_records()]
    return json.dumps(data, indent=1, allow_nan=False) + "\n"
