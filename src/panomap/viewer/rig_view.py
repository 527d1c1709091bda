"""A rig in the viewer: each camera's lookup and the edge of what it sees, the pictures in one texture, and the
gains of a view, as the page's GPU takes them.

Convention (docs/conventions.md, "A rig"; :mod:`panomap.rig.blend`): the page draws a rig's view as
``panomap perspective RIG ...`` blends it. For each output pixel's ray (world axes; for a floor map, the point's
ray from each camera's own position) every camera is read through its lookup
(:func:`~panomap.viewer.table_texture.lookup_texture`), and the cameras that see it are weighed as
:func:`~panomap.rig.blend.feather_weights` weighs them, ``w_k = max(0, d_k - d_max + 2 f)`` over their sum, each
scaled by its gain. ``d_k``, the pixel's distance (output px) from the edge of what camera k sees, is found on
the GPU from ``g_k = edge_k(psi) - alpha``, the ray's angle inside that edge (rad: ``alpha`` off the camera's
axis, ``edge_k(psi)`` the edge's angle at its azimuth psi about the axis, :func:`edge_profile`), which each
lookup texel carries beside its (u, v) (:func:`rig_lookup`): ``d_k = g_k / |grad g_k|``, the gradient over
output pixels (the screen's derivatives), the first-order distance to that edge, where the library measures
the distance to the nearest pixel the camera does not see (a distance transform of the view). The two agree
where the edge is a smooth curve within the view (a perspective view across a seam: weights within 0.02); they
part where the view cuts the edge off or stretches it (an equirect's rows near the poles), docs/viewer.md says
by how much.

The gains are the library's (:meth:`~panomap.rig.blend.RigRemapper.layer_gains`) for the view the page shows,
from its still pictures or a video's first frame, found here on request (:func:`view_gains`).
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from ..errors import PanomapError
from ..geometry import inside_image
from ..io.images import MAX_IMAGE_PIXELS, UNKNOWN_FORMAT, check_same_depth, encode_png, read_image
from ..rig import CameraRig, RigRemapper, camera_maps
from ..rig.blend import WRAPPING_KINDS, alike_pictures
from ..table.table import PanoMappingTable
from ..video.source import first_frame
from ..views.spec import parse_view_spec
from .source import Source, display_image, open_source
from .table_texture import lookup_frame, lookup_texture, table_description

# The most cameras the page draws (each takes a texture unit; WebGL2 guarantees 16, the page uses 5 more).
MAX_VIEWER_CAMERAS = 8
# Azimuths about a camera's axis at which the edge of what it sees is found (the profile wraps).
EDGE_AZIMUTHS = 360
# The edge's search: a coarse step off the axis (rad), then bisections (to 0.25 deg / 2^10, 0.0002 deg).
EDGE_STEP_RAD = math.radians(0.25)
EDGE_BISECTIONS = 10
# Pixels of edge replicated around each picture laid out in the page's texture (bilinear reads reach 1 px out).
PICTURE_MARGIN = 2
# Views' gains kept (the page asks again for a view it showed before).
GAINS_KEPT = 16


def edge_profile(table: PanoMappingTable, frame: NDArray[np.float64]) -> NDArray[np.float32]:
    """(EDGE_AZIMUTHS + 1,) float32: the largest angle (rad) off the camera's axis that it sees, at azimuths
    ``psi = -pi + 2 pi i / EDGE_AZIMUTHS`` about it (the last repeats the first).

    ``frame`` (3 x 3, rows e1, e2, e3; :func:`~panomap.viewer.table_texture.lookup_frame`) holds the axes: the
    optical axis is ``-e3`` and ``psi = atan2(e . e2, e . e1)``. A ray is seen where the table has an entry
    for it on the image (as the library's maps: NaN elsewhere). Found by stepping out from the axis by
    :data:`EDGE_STEP_RAD` to the first ray not seen, then bisecting.
    """
    psi = -math.pi + 2 * math.pi * np.arange(EDGE_AZIMUTHS) / EDGE_AZIMUTHS
    e1, e2, e3 = frame

    def seen(alpha: NDArray[np.float64]) -> NDArray[np.bool_]:
        """Whether the camera sees the rays ``alpha`` (rad) off its axis at ``psi`` (broadcast)."""
        around = np.cos(psi)[..., None] * e1 + np.sin(psi)[..., None] * e2
        rays = np.cos(alpha)[..., None] * -e3 + np.sin(alpha)[..., None] * around
        theta = np.arctan2(rays[..., 1], rays[..., 0]) % (2 * math.pi)
        rho = np.arctan2(rays[..., 2], np.hypot(rays[..., 0], rays[..., 1]))
        uv = table.sample(theta, rho)
        with np.errstate(invalid="ignore"):
            return np.asarray(inside_image(uv[..., 0], uv[..., 1], table.image_size))  # type: ignore[arg-type]

    steps = np.arange(0.0, math.pi + EDGE_STEP_RAD, EDGE_STEP_RAD)
    unseen = ~seen(np.broadcast_to(steps[:, None], (steps.size, psi.size)))
    first = np.where(unseen.any(axis=0), np.argmax(unseen, axis=0), steps.size - 1)
    low = steps[np.maximum(first - 1, 0)]
    high = steps[first]
    for _ in range(EDGE_BISECTIONS):
        middle = 0.5 * (low + high)
        inside = seen(middle)
        low, high = np.where(inside, middle, low), np.where(inside, high, middle)
    edge = 0.5 * (low + high)
    return np.append(edge, edge[0]).astype(np.float32)


def picture_layout(sizes: list[tuple[int, int]]) -> tuple[list[tuple[int, int]], tuple[int, int]]:
    """Where each picture of ``sizes`` (w, h) sits in the page's texture (its top-left pixel) when the rig's
    cameras each have their own: in a grid of ``ceil(sqrt(k))`` columns, each with :data:`PICTURE_MARGIN` px
    of its edge around it; and the texture's (width, height)."""
    columns = math.ceil(math.sqrt(len(sizes)))
    cell_w = max(w for w, _ in sizes) + 2 * PICTURE_MARGIN
    cell_h = max(h for _, h in sizes) + 2 * PICTURE_MARGIN
    rows = math.ceil(len(sizes) / columns)
    places = [
        (k % columns * cell_w + PICTURE_MARGIN, k // columns * cell_h + PICTURE_MARGIN) for k in range(len(sizes))
    ]
    return places, (columns * cell_w, rows * cell_h)


def one_picture(rig: CameraRig, pictures: list[NDArray[Any]]) -> tuple[NDArray[Any], list[tuple[int, int]]]:
    """The texture the page reads (H, W[, C]) and each camera's offset in it (px): the rig's one frame as it
    is, or its cameras' pictures laid out by :func:`picture_layout`, each with its edge replicated around it
    (what ``BORDER_REPLICATE`` reads beyond it in the library)."""
    if rig.offsets is not None:
        return pictures[0], list(rig.offsets)
    sizes = [(p.shape[1], p.shape[0]) for p in pictures]
    places, (width, height) = picture_layout(sizes)
    out = np.zeros((height, width, *pictures[0].shape[2:]), dtype=pictures[0].dtype)
    m = PICTURE_MARGIN
    for picture, (x, y), (w, h) in zip(pictures, places, sizes, strict=True):
        padded = cv2.copyMakeBorder(picture, m, m, m, m, cv2.BORDER_REPLICATE)
        out[y - m : y + h + m, x - m : x + w + m] = padded.reshape(out[y - m : y + h + m, x - m : x + w + m].shape)
    return out, places


def rig_lookup(table: PanoMappingTable) -> tuple[NDArray[np.float32], dict[str, Any]] | None:
    """The camera's lookup for a rig's view: (S, S, 4) float32 texels ``(u, v, g, 0)`` and its description (as
    :func:`~panomap.viewer.table_texture.lookup_texture`'s); None where the camera has no lookup.

    ``g`` (rad) is the texel's ray's angle inside the edge of what the camera sees, ``edge(psi) - alpha``
    (:func:`edge_profile`; negative beyond it), everywhere (where (u, v) is :data:`NO_ENTRY` too). A texel's ray:
    ``p = ((X, Y) - centre) / scale``, ``e = (2 p, -pole (|p|^2 - 1)) / (1 + |p|^2)`` in the lookup's axes
    (``frame``), the inverse of the page's ``p = e_xy / (|e| + pole e_z)``.
    """
    lookup = lookup_texture(table)
    if lookup is None:
        return None
    texels, described = lookup
    side, centre, scale, pole = described["side"], described["centre"], described["scale"], described["pole"]
    p = (np.arange(side) - centre) / scale
    px, py = np.meshgrid(p, p)
    q = 1.0 + px * px + py * py
    local = np.stack([2 * px / q, 2 * py / q, -pole * (px * px + py * py - 1.0) / q], axis=-1)
    rays = local @ np.asarray(described["frame"], dtype=np.float64)
    frame = lookup_frame(table)
    edge = edge_profile(table, frame)
    axes = rays @ frame.T
    psi = np.arctan2(axes[..., 1], axes[..., 0])
    alpha = np.arccos(np.clip(-axes[..., 2], -1.0, 1.0))
    at = (psi + math.pi) / (2 * math.pi) * EDGE_AZIMUTHS
    g = np.interp(at, np.arange(EDGE_AZIMUTHS + 1), edge) - alpha
    out = np.zeros((side, side, 4), dtype=np.float32)
    out[..., :2] = texels
    out[..., 2] = g
    return out, described


@dataclass(frozen=True)
class RigTextures:
    """What the page reads of a rig: ``description`` (JSON: each camera's lookup, offset, image size; see
    :func:`rig_textures`) and each camera's lookup (:func:`rig_lookup`) as little-endian float32 bytes."""

    description: dict[str, Any]
    lookups: list[bytes]


def rig_textures(rig: CameraRig, offsets: list[tuple[int, int]]) -> RigTextures:
    """The rig's textures for the page, each camera's picture at ``offsets`` in the one texture.

    The description has, per camera: ``name``, ``image_size``, ``offset``, ``lookup``
    (:func:`~panomap.viewer.table_texture.lookup_texture`'s description), ``sine_range`` (the sines of its
    table's elevation range), ``position`` (world).

    Raises
    ------
    PanomapError
        When the rig has more cameras than the page draws, or a camera has no lookup (it sees too far round).
    """
    if rig.count > MAX_VIEWER_CAMERAS:
        raise PanomapError(f"the viewer shows rigs of at most {MAX_VIEWER_CAMERAS} cameras, not {rig.count}")
    cameras, lookups = [], []
    for name, table, offset in zip(rig.names, rig.tables, offsets, strict=True):
        lookup = rig_lookup(table)
        if lookup is None:
            raise PanomapError(f"the rig's camera {name} sees too far round its axis for the viewer's lookup")
        texels, described = lookup
        lookups.append(texels.astype("<f4").tobytes())
        rho_s, rho_e = table.elevation_range
        cameras.append(
            {
                "name": name,
                "image_size": list(table.image_size),  # type: ignore[arg-type]
                "offset": list(offset),
                "lookup": described,
                "sine_range": [math.sin(rho_s), math.sin(rho_e)],
                "position": [float(c) for c in table.camera_position],
            }
        )
    description = {"cameras": cameras, "reference": table_description(rig.tables[0])}
    return RigTextures(description, lookups)


class ViewGains:
    """The library's gains of a rig's views of fixed pictures (one per camera, or one frame), by view spec."""

    def __init__(self, rig: CameraRig, pictures: list[NDArray[Any]]) -> None:
        self.rig = rig
        self.pictures = pictures
        self._kept: dict[str, list[list[float]]] = {}
        self._lock = threading.Lock()  # (pages ask from the server's threads; one view is worked out at a time)

    def __call__(self, spec: str) -> list[list[float]]:
        """(k, C) gains, BGR order, of the view ``spec`` (``panomap.views.spec``), as ``panomap perspective
        RIG ...`` finds them.

        Raises
        ------
        PanomapError
            When the spec is not a view.
        """
        with self._lock:
            if spec in self._kept:
                return self._kept[spec]
            _, view = parse_view_spec(spec)
            maps = camera_maps(self.rig, view)
            remapper = RigRemapper(self.rig, maps, wrap=view.kind in WRAPPING_KINDS)
            gains = remapper.layer_gains(remapper.layers(self.pictures))
            answer = [[float(g) for g in row] for row in gains]
            self._kept[spec] = answer
            while len(self._kept) > GAINS_KEPT:
                self._kept.pop(next(iter(self._kept)))
            return answer


@dataclass(frozen=True)
class RigView:
    """A rig and its pictures as the viewer serves them: the rig's file name, the textures, the gains of any
    view (:class:`ViewGains`), the file names of the pictures given (for the page's command line)."""

    name: str
    textures: RigTextures
    gains: ViewGains
    pictures: tuple[str, ...]


def open_rig_source(rig: CameraRig, rig_name: str, names: list[str]) -> tuple[RigView, Source]:
    """The rig's view and the source the page reads: one frame holding every camera (an image or a video
    file), or one still picture per camera, in the rig's order, laid out in one image.

    Raises
    ------
    PanomapError
        Naming the input, when the count or a size is wrong, a camera's picture is a video, or the source is
        live (its gains need a frame here).
    """
    if rig.offsets is not None:
        if len(names) != 1:
            raise PanomapError(f"the rig's {rig.count} cameras share one frame: give that one picture or video, "
                               f"not {len(names)}")  # fmt: skip
        source = open_source(names[0])
        if source.kind == "live":
            raise PanomapError("the viewer shows a rig's pictures or video file, not a live stream", names[0])
        if source.size != rig.frame_size:
            width, height = source.size
            expected = rig.frame_size
            raise PanomapError(
                f"its frames are {width} x {height}, the rig {rig_name} holds its cameras in {expected[0]} x "  # type: ignore[index]
                f"{expected[1]} frames",  # type: ignore[index]
                names[0],
            )
        if source.kind == "image":
            pictures = [read_image(names[0])]
        else:
            frame = first_frame(names[0], MAX_IMAGE_PIXELS)
            if frame is None:
                raise PanomapError("no frame could be read from it", names[0])
            pictures = [frame]
        offsets = list(rig.offsets)
    else:
        if len(names) != rig.count:
            raise PanomapError(f"give one picture per camera of the rig {rig_name}, in its order "
                               f"({', '.join(rig.names)}), not {len(names)}")  # fmt: skip
        pictures = []
        for name, camera, table in zip(names, rig.names, rig.tables, strict=True):
            if Path(name).is_file() and _is_video_file(name):
                raise PanomapError(f"the viewer takes a still picture per camera ({camera} here): blend a rig's "
                                   "videos with panomap video", name)  # fmt: skip
            pictures.append(read_image(name, table.image_size, f"camera {camera}"))
        check_same_depth(names, pictures)
        pictures = alike_pictures(pictures)  # (grey beside colour: repeated into B, G, R)
        composite, offsets = one_picture(rig, pictures)
        shown = display_image(composite)
        height, width = shown.shape[:2]
        source = Source(" ".join(names), "image", (width, height), image_png=encode_png(shown))
    shown_names = tuple(Path(name).name for name in names)
    view = RigView(rig_name, rig_textures(rig, offsets), ViewGains(rig, pictures), shown_names)
    return view, source


def _is_video_file(name: str) -> bool:
    """Whether ``name`` is not an image panomap reads but a file PyAV decodes."""
    try:
        read_image(name, None)
    except PanomapError as exc:
        return exc.detail == UNKNOWN_FORMAT
    return False
