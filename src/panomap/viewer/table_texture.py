"""A pano-mapping table as the page's GPU takes it: one float texture, and what the shader needs to read it.

The shader reads the table bilinearly by hand (as ``panomap.table.sampling`` does on the CPU): the
four entries around a ray's fractional indices (fi, fj), the azimuth wrapping and the last elevation
cell continuing the line through the last two entries. To need two texture reads per pixel, not four,
each texel holds two entries one elevation apart, as RGBA 32-bit floats (0.0001 px at 2000 px, far
below the 0.05 px the viewer must keep):

    texel (column c, row b*(N + 1) + j) = (u, v) of entry (i, j), then (u, v) of entry (i, j + 1)

with ``i = b*B + c`` the azimuth index, ``B`` = :func:`block_width` azimuths per block of rows (so that
the texture fits the 2048 texels a side every WebGL2 GPU takes), each block one column wider than B
(its last column is the next block's first, so that a cell's two columns are always in one block),
``i = M`` the same as ``i = 0`` (the wrap), and rows ``j = N`` and ``N + 1`` the extrapolated ones
(``2 E[N-1] - E[N-2]``, then the same again). Entries where the camera sees nothing (NaN in the table)
are sent as :data:`NO_ENTRY`, which the shader treats as ``cv2.remap`` treats NaN: an output pixel
reading one has no source.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import PanomapError
from ..table.table import PanoMappingTable
from ..views.lookup import direction_lookup

# Texels a side every WebGL2 GPU takes (its MAX_TEXTURE_SIZE is at least this).
GUARANTEED_SIDE = 2048
# The most texture rows the page asks for (the page checks its GPU's limit too).
MAX_TEXTURE_ROWS = 16384
# An entry the camera does not see (NaN in the table): far below any pixel, and a float32 exactly.
NO_ENTRY = -1.0e6


def block_width(table: PanoMappingTable) -> int:
    """B: azimuths per block of texture rows (the texture is B + 1 texels wide)."""
    return min(table.size[0], GUARANTEED_SIDE - 1)


def padded_entries(table: PanoMappingTable) -> NDArray[np.float32]:
    """The entries (M + 1, N + 2, 2): azimuth M repeats azimuth 0, rows N and N + 1 continue the last cell's
    line; NaN as :data:`NO_ENTRY`."""
    m, n = table.size
    out = np.empty((m + 1, n + 2, 2), dtype=np.float32)
    out[:m, :n] = table.entries
    out[m, :n] = table.entries[0]
    # 2a - b of float32 values is exact in float64: rounded once to float32, as the CPU's sampling rounds it.
    out[:, n] = (2.0 * out[:, n - 1].astype(np.float64) - out[:, n - 2]).astype(np.float32)
    out[:, n + 1] = out[:, n]
    out[~np.isfinite(out).all(axis=-1)] = NO_ENTRY
    return out


def texture_data(table: PanoMappingTable) -> NDArray[np.float32]:
    """The texture (rows, B + 1, 4) float32 (see the module docstring).

    Raises
    ------
    PanomapError
        When the texture would need more than :data:`MAX_TEXTURE_ROWS` rows.
    """
    m, n = table.size
    width = block_width(table)
    blocks = texture_blocks(table)
    padded = padded_entries(table)
    texture = np.full((blocks * (n + 1), width + 1, 4), NO_ENTRY, dtype=np.float32)
    for b in range(blocks):
        first = b * width
        columns = padded[first : min(first + width + 1, m + 1)]  # (c, N + 2, 2)
        rows = slice(b * (n + 1), (b + 1) * (n + 1))
        count = columns.shape[0]
        texture[rows, :count, 0:2] = np.transpose(columns[:, : n + 1], (1, 0, 2))
        texture[rows, :count, 2:4] = np.transpose(columns[:, 1 : n + 2], (1, 0, 2))
    return texture


def texture_blocks(table: PanoMappingTable) -> int:
    """Blocks of N + 1 texture rows (see the module docstring)."""
    m, n = table.size
    blocks = -(-m // block_width(table))
    if blocks * (n + 1) > MAX_TEXTURE_ROWS:
        raise PanomapError(
            f"the table's {m} x {n} entries need a texture of {blocks * (n + 1)} rows, more than GPUs take "
            f"({MAX_TEXTURE_ROWS}); make a smaller table"
        )
    return blocks


def texture_bytes(table: PanoMappingTable) -> bytes:
    """:func:`texture_data` as little-endian float32 bytes, row by row."""
    return texture_data(table).astype("<f4", copy=False).tobytes()


def table_description(table: PanoMappingTable) -> dict[str, Any]:
    """What the page needs besides the entries: sizes, elevation range (rad), image size, camera position,
    axis, whether the camera's height is known (a table learned from lines without ``--camera-height``
    does not know it: the floor map says so), and the texture's layout."""
    m, n = table.size
    rho_s, rho_e = table.elevation_range
    x0, y0, z0 = (float(c) for c in table.camera_position)
    height_known = bool(table.info.get("camera_height_known", True))
    return {
        "M": m,
        "N": n,
        "rho_s": rho_s,
        "rho_e": rho_e,
        "image_size": list(table.image_size) if table.image_size is not None else None,
        "camera_position": [x0, y0, z0],
        "axis": table.model.axis,
        "camera_height_known": height_known and math.isfinite(z0),
        "block_width": block_width(table),
        "texture_width": block_width(table) + 1,
        "texture_rows": texture_blocks(table) * (n + 1),
        "no_entry": NO_ENTRY,
    }


def lookup_texture(table: PanoMappingTable) -> tuple[NDArray[np.float32], dict[str, Any]] | None:
    """The table's direction lookup (:mod:`panomap.views.lookup`, what ``panomap perspective`` and ``floor``
    read their rays from) as an (S, S, 2) float32 texture of (u, v) and its description; None where the table
    has none.

    A ray d is read at texel ``(X, Y) = centre + scale * (d_x, d_y) / (|d| + pole * d_z)`` (bilinear, texel
    centres at integers) and has a source where ``d_z / |d|`` lies within the sines of the table's elevation
    range (and its pixel on the image). Texels without an entry (NaN) are :data:`NO_ENTRY`.
    """
    lookup = direction_lookup(table)
    if lookup is None:
        return None
    texture = np.stack([lookup.u, lookup.v], axis=-1).astype(np.float32)
    texture[~np.isfinite(texture).all(axis=-1)] = NO_ENTRY
    description = {
        "side": int(lookup.u.shape[0]),
        "pole": lookup.pole,
        "scale": lookup.scale,
        "centre": lookup.centre,
    }
    return texture, description
