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

from ..camera.orientation import optical_axis
from ..errors import PanomapError
from ..table.table import PanoMappingTable
from ..views.lookup import EDGE_TEXELS, LOOKUP_ERROR_PX, LOOKUP_STEPS, MAX_LOOKUP_SIDE, direction_lookup
from ..views.perspective import default_direction

# Texels a side every WebGL2 GPU takes (its MAX_TEXTURE_SIZE is at least this).
GUARANTEED_SIDE = 2048
# The most texture rows the page asks for (the page checks its GPU's limit too).
MAX_TEXTURE_ROWS = 16384
# An entry the camera does not see (NaN in the table): far below any pixel, and a float32 exactly.
NO_ENTRY = -1.0e6
# Random rays on which a turned camera's lookup is checked against the table's exact sampling.
TURNED_ERROR_RAYS = 20_000


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
    axis, the perspective view's default direction (:func:`~panomap.views.perspective.default_direction`),
    whether the camera's height is known (a table learned from lines without ``--camera-height``
    does not know it: the floor map says so), and the texture's layout."""
    m, n = table.size
    rho_s, rho_e = table.elevation_range
    x0, y0, z0 = (float(c) for c in table.camera_position)
    height_known = bool(table.info.get("camera_height_known", True))
    yaw, pitch, roll = table.model.orientation
    return {
        "M": m,
        "N": n,
        "rho_s": rho_s,
        "rho_e": rho_e,
        "image_size": list(table.image_size) if table.image_size is not None else None,
        "camera_position": [x0, y0, z0],
        "axis": table.model.axis,
        "orientation_deg": [math.degrees(yaw), math.degrees(pitch), math.degrees(roll)],
        "default_view_deg": [math.degrees(angle) for angle in default_direction(table)],
        "camera_height_known": height_known and math.isfinite(z0),
        "block_width": block_width(table),
        "texture_width": block_width(table) + 1,
        "texture_rows": texture_blocks(table) * (n + 1),
        "no_entry": NO_ENTRY,
    }


def lookup_texture(table: PanoMappingTable) -> tuple[NDArray[np.float32], dict[str, Any]] | None:
    """The lookup the page reads rays from, as an (S, S, 2) float32 texture of (u, v) and its description;
    None where the table has none (the page then reads the table itself, with two arctangents a pixel).

    A table with the CLI's direction lookup (:mod:`panomap.views.lookup`, what ``panomap perspective`` and
    ``floor`` read) sends it; a turned camera's table, whose range reaches too far past the horizon for
    that one (a fisheye looking ahead sees elevations -90..90 deg), sends :func:`turned_lookup`, the same
    projection about the camera's own optical axis. The description's ``frame`` (3 x 3, rows) takes a
    world ray d to the lookup's axes (the identity for the CLI's lookup): a ray is read at texel
    ``(X, Y) = centre + scale * (e_x, e_y) / (|e| + pole * e_z)``, ``e = frame @ d`` (bilinear, texel
    centres at integers), and has a source where ``d_z / |d|`` lies within the sines of the table's
    elevation range (and its pixel on the image). Texels without an entry (NaN) are :data:`NO_ENTRY`.
    """
    lookup = direction_lookup(table)
    if lookup is not None:
        u, v, pole, scale, centre = lookup.u, lookup.v, lookup.pole, lookup.scale, lookup.centre
        frame = np.eye(3)
    else:
        turned = turned_lookup(table)
        if turned is None:
            return None
        (u, v), frame, scale, centre = turned
        pole = -1.0
    texture = np.stack([u, v], axis=-1).astype(np.float32)
    texture[~np.isfinite(texture).all(axis=-1)] = NO_ENTRY
    description = {
        "side": int(u.shape[0]),
        "pole": pole,
        "scale": scale,
        "centre": centre,
        "frame": [[float(x) for x in row] for row in frame],
    }
    return texture, description


def lookup_frame(table: PanoMappingTable) -> NDArray[np.float64]:
    """(3, 3) rotation, rows e1, e2, e3: world rays to a turned camera's lookup axes, ``e3`` pointing away
    from its optical axis (so that the axis is the lookup's centre, as straight down is a level lookup's)."""
    axis = optical_axis(table.model.rotation, table.model.axis)
    e3 = -axis / np.linalg.norm(axis)
    helper = np.array([0.0, 0.0, 1.0]) if abs(e3[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    e1 = np.cross(helper, e3)
    e1 /= np.linalg.norm(e1)
    return np.stack([e1, np.cross(e3, e1), e3])


def turned_lookup(
    table: PanoMappingTable,
) -> tuple[tuple[NDArray[np.float32], NDArray[np.float32]], NDArray[np.float64], float, float] | None:
    """A turned camera's lookup: ((u, v), frame, scale, centre), or None for a level camera's table, or
    a camera that sees too far from its axis for :data:`~panomap.views.lookup.MAX_LOOKUP_SIDE` texels.

    As :func:`~panomap.views.lookup.make_lookup`, about the camera's optical axis instead of the vertical:
    texel (X, Y) holds the table sampled exactly (bilinear, NaN where the camera does not see) at the ray
    whose stereographic point from the pole behind the camera is ``p = ((X, Y) - centre) / scale``, in the
    axes of :func:`lookup_frame`. The step (rad between texels at the axis) is the coarsest of
    :data:`~panomap.views.lookup.LOOKUP_STEPS` whose bilinear reading is within
    :data:`~panomap.views.lookup.LOOKUP_ERROR_PX` of the exact sampling on random rays, else the finest
    that fits.
    """
    if table.model.rotation is None or table.camera_elevation_range is None:
        return None
    low, high = table.camera_elevation_range
    far = high + math.pi / 2 if table.model.axis == "down" else math.pi / 2 - low  # from the optical axis
    if far >= math.pi - 1e-6:
        return None
    frame = lookup_frame(table)
    rng = np.random.default_rng(0)
    rays = rng.normal(size=(TURNED_ERROR_RAYS, 3))
    rays /= np.linalg.norm(rays, axis=1, keepdims=True)
    exact = _sample_rays(table, rays)
    best = None
    for step in LOOKUP_STEPS:
        scale = 2.0 / step  # dp/dangle is 1/2 at the axis
        half = math.ceil(scale * math.tan(far / 2) + EDGE_TEXELS)
        if 2 * half + 1 > MAX_LOOKUP_SIDE:
            break
        centre = float(half)
        p = (np.arange(2 * half + 1) - centre) / scale
        px, py = np.meshgrid(p, p)
        q = 1.0 + px * px + py * py
        local = np.stack([2 * px / q, 2 * py / q, (q - 2.0) / q], axis=-1)  # unit; p = 0 is -e3, the axis
        uv = _sample_rays(table, local @ frame)
        best = ((uv[..., 0].copy(), uv[..., 1].copy()), frame, scale, centre)
        if _read_error(uv, rays @ frame.T, scale, centre, exact) <= LOOKUP_ERROR_PX:
            break
    return best


def _sample_rays(table: PanoMappingTable, rays: NDArray[np.float64]) -> NDArray[np.float32]:
    """The table sampled (bilinear, NaN unseen) at world rays (..., 3)."""
    theta = np.arctan2(rays[..., 1], rays[..., 0]) % (2 * math.pi)
    rho = np.arctan2(rays[..., 2], np.hypot(rays[..., 0], rays[..., 1]))
    return table.sample(theta, rho)


def _read_error(
    uv: NDArray[np.float32], local: NDArray[np.float64], scale: float, centre: float, exact: NDArray[np.float32]
) -> float:
    """Largest difference (px) between the lookup ``uv`` read bilinearly (as the GPU does, float weights)
    at rays ``local`` (its axes) and the ``exact`` sampling, over rays with a source both ways."""
    side = uv.shape[0]
    with np.errstate(divide="ignore", invalid="ignore"):
        x = centre + scale * local[:, 0] / (1.0 - local[:, 2])
        y = centre + scale * local[:, 1] / (1.0 - local[:, 2])
    inside = np.isfinite(x) & np.isfinite(y) & (x >= 0) & (y >= 0) & (x < side - 1) & (y < side - 1)
    x, y, exact = x[inside], y[inside], exact[inside]
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    tx, ty = (x - x0)[:, None], (y - y0)[:, None]
    read = (1 - ty) * ((1 - tx) * uv[y0, x0] + tx * uv[y0, x0 + 1]) + ty * (
        (1 - tx) * uv[y0 + 1, x0] + tx * uv[y0 + 1, x0 + 1]
    )
    both = np.isfinite(read).all(axis=-1) & np.isfinite(exact).all(axis=-1)
    return float(np.max(np.abs(read - exact)[both])) if both.any() else 0.0
