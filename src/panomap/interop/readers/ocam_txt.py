"""OCamCalib's ``calib_results.txt`` (written by its ``export_data.m``; read by ``ocam_functions.c``).

Five data lines, each after comment lines starting with ``#``:

1. ``N a0 a1 ... a(N-1)``: the direct polynomial ``pol`` (``ss``), its length first;
2. ``M p0 p1 ... p(M-1)``: the inverse polynomial ``invpol``, its length first;
3. ``xc yc``: the centre, **row then column**, from 0;
4. ``c d e``: the affine parameters;
5. ``height width``.

The model and its frame: :mod:`panomap.interop.models.ocam`.
"""

from __future__ import annotations

from pathlib import Path

from ...errors import PanomapError
from ..models.ocam import OCam
from .base import Imported, built, image_size_of, number

FIELDS = (
    "pol (the direct polynomial)",
    "invpol (the inverse polynomial)",
    "centre (xc yc)",
    "affine (c d e)",
    "image size (height width)",
)


def looks_like(text: str) -> bool:
    return "polynomial coefficients for the DIRECT mapping" in text or text.lstrip().startswith("#polynomial")


def read(text: str, path: str | Path, choice: str | None = None) -> Imported:
    lines = [line.split() for line in text.splitlines() if line.strip() and not line.lstrip().startswith("#")]
    if len(lines) < len(FIELDS):
        raise PanomapError(f"{FIELDS[len(lines)]} is missing (found {len(lines)} of 5 data lines)", path)
    values: list[list[float]] = []
    for name, line in zip(FIELDS, lines, strict=False):
        try:
            values.append([float(x) for x in line])
        except ValueError:
            raise PanomapError(f"{name}: {' '.join(line)[:60]!r} is not a list of numbers", path) from None
        for value in values[-1]:
            number(value, name, path)
    polynomials = []
    for name, row in zip(FIELDS[:2], values[:2], strict=True):
        count = row[0]
        if count != int(count) or int(count) != len(row) - 1:
            raise PanomapError(f"{name} declares {count:g} coefficients and lists {len(row) - 1}", path)
        polynomials.append(tuple(row[1:]))
    for name, row, count in zip(FIELDS[2:], values[2:5], (2, 3, 2), strict=True):
        if len(row) != count:
            raise PanomapError(f"{name} has {len(row)} values, expected {count}", path)
    (xc, yc), (c, d, e), (height, width) = values[2], values[3], values[4]
    width_px, height_px = image_size_of(width, height, FIELDS[4], path)
    model = built(OCam, path, polynomials[0], polynomials[1], xc, yc, c, d, e, height_px, width_px)
    assert isinstance(model, OCam)
    inscribed = min(xc + 0.5, yc + 0.5, height_px - 0.5 - xc, width_px - 0.5 - yc)
    if model.turn_radius_px < inscribed:
        raise PanomapError(
            f"{FIELDS[0]} turns back at a radius of {model.turn_radius_px:.1f} px, inside the image "
            f"({inscribed:.1f} px from the centre to its nearest edge)",
            path,
        )
    return Imported(model, "ocam", (width_px, height_px))
