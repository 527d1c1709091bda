"""One view of a rig: each camera's map, the feathered weights across the overlaps, the gains, the blend.

Convention: maps as :mod:`panomap.remap` ((H, W, 2) float32 source (u, v), NaN where there is no source), in
each camera's own picture or, for a rig whose pictures share one frame, in the frame (its offset added).

- **Each camera's map** (:func:`camera_maps`) is the view seen from that camera's own position: a view of
  directions (the panoramas, the perspective view) at infinity is the same rays for every camera; given a
  distance, or a view of a surface (cylinder, plane, floor), each output pixel's point (relative to camera 0,
  the rig's reference) is seen along the ray from each camera's own O_m, so the floor map is exact for every
  camera.
- **Weights** (:func:`feather_weights`): where several cameras see a pixel, each counts by its distance ``d``
  (output px) from the edge of what it sees, as OpenCV's feather blender weighs, within a band about the seam:
  ``w_k = max(0, d_k - d_max + 2 f)``, ``d_max`` the largest of the cameras' distances there and ``f`` the feather
  (default 1% of the view's diagonal, at least 8 px), over their sum. The seam is where two cameras' distances
  are equal; the weights cross it linearly over about ``2 f`` px and sum to 1; away from it the camera that sees
  the pixel deepest takes it alone (a narrow band: less ghosting of near objects, and less to blend). Panoramas
  wrap in azimuth, and so do their distances.
- **Gains** (:func:`overlap_gains`): each camera's gain per channel, from the overlaps' means, by least squares
  with a prior of 1 (as OpenCV's gain compensator): a lens 15% brighter than its neighbour is matched before
  the blend, so no step shows at the seam. Then scaled so that their mean over the view (each camera weighed by
  its share of it) is 1: the least squares alone shrinks every gain where the overlaps' ratios do not agree
  round a ring of cameras (a surround view's panorama, near objects differing between cameras: 0.66-0.80, the
  view 20% darker than every camera's own).
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .. import inputs
from ..errors import PanomapError
from ..remap import Remapper
from ..table.table import PanoMappingTable
from ..views import View, build_map
from ..views.base import check_view
from .rig import CameraRig
from .seams import SeamWeights, seam_weights

# Views whose columns wrap around in azimuth: their weights' distances wrap too.
WRAPPING_KINDS = ("panorama", "equirect")
# Overlap pixels where both weights are at least this count for the gains.
GAIN_MIN_WEIGHT = 0.1
# The gains' prior: the overlaps' mean differences (grey levels) against a gain's distance from 1.
GAIN_NOISE = 10.0
GAIN_PRIOR = 1.0

# Memory a rig's view takes (bytes): per pixel of the view for each camera (its map, its remap's maps, its
# layer, its weights) and once (the blend, the output). Peak RSS of equirect views of 4000 x 2000 from rigs of
# 1, 2 and 4 cameras (1024 x 1024 pictures): 0.73, 1.34 and 2.14 GB, each within these (0.92, 1.52, 2.72 GB).
RIG_VIEW_BYTES_PER_CAMERA_PIXEL = 75
RIG_VIEW_BYTES_PER_PIXEL = 40


def rig_view_bytes(size: tuple[int, int], cameras: int) -> int:
    """The memory (bytes, about, erring high) a view of ``size`` (W, H) px of a rig of ``cameras`` takes made."""
    pixels = int(size[0]) * int(size[1])
    return pixels * (RIG_VIEW_BYTES_PER_CAMERA_PIXEL * int(cameras) + RIG_VIEW_BYTES_PER_PIXEL)


def camera_maps(rig: CameraRig, view: View, sampling: str = "bilinear", threads: int = 1) -> list[NDArray[np.float32]]:
    """Each camera's (H, W, 2) map of ``view``, in its own picture's pixels (NaN where it does not see).

    Parameters
    ----------
    rig : CameraRig
    view : View
        Any view; a view of directions at infinity (unless it has a distance), a surface's points seen from each
        camera's own position (relative to camera 0's, the rig's reference). Its values taken from a table (a
        default size, a perspective view's axis) are camera 0's, so that every camera's map has one shape.
    sampling : {"bilinear", "nearest"}
        How the tables are read.
    threads : int
        Cameras whose maps are made at once, each on its own thread (NumPy and OpenCV let go of the GIL; each
        camera's map is the same either way).
    """
    inputs.instance(rig, CameraRig, "the rig", " (one camera's table: panomap.build_map)")
    check_view(view)
    threads = inputs.whole_numbers((threads,), 1, "threads")[0]
    if threads < 1:
        raise PanomapError(f"threads must be 1 or more, not {threads}")
    reference = rig.tables[0]
    view = view.resolved(reference)
    if getattr(view, "size", ()) is None:  # a size each table would choose for itself: camera 0's, for every camera
        view = replace(view, size=view.output_size(reference))  # type: ignore[type-var]
    points = view.points(reference)

    def camera_map(table: PanoMappingTable) -> NDArray[np.float32]:
        if points is None:
            return build_map(table, view, sampling)
        shift = rig.reference - np.asarray(table.camera_position, dtype=np.float64)
        theta, rho = table.model.point_angles(points + shift)
        return table.sample(theta.astype(np.float32), rho.astype(np.float32), sampling, overwrite=True)

    if threads > 1 and rig.count > 1:
        with ThreadPoolExecutor(min(threads, rig.count), thread_name_prefix="panomap-maps") as pool:
            return list(pool.map(camera_map, rig.tables))
    return [camera_map(table) for table in rig.tables]


def feather_weights(
    maps: list[NDArray[np.float32]], wrap: bool = False, feather_px: float | None = None
) -> NDArray[np.float32]:
    """(k, H, W) float32 weights: each camera's distance (px) from the edge of what it sees, less the largest
    camera's distance there and plus ``2 feather_px`` (at least 0), over their sum where several see a pixel; 0
    where none does. ``wrap``: the columns wrap around (a panorama). ``feather_px``: default
    :func:`.seams.default_feather_px`; ``inf`` weighs by the distances alone across the whole overlap. (Computed on the
    overlap alone, :func:`.seams.seam_weights`.)"""
    return seam_weights(maps, wrap, feather_px).dense()


def overlap_gains(
    layers: list[NDArray[np.float32]], weights: NDArray[np.float32], shares: NDArray[np.float64] | None = None
) -> NDArray[np.float64]:
    """(k, C) gains from the overlaps' means: minimise, over every pair's overlap (its pixel count N_ij),
    ``N_ij ((g_i m_ij - g_j m_ji)^2 / GAIN_NOISE^2 + (1 - g_i)^2 / GAIN_PRIOR^2)`` per channel, ``m_ij`` camera
    i's mean there; then scaled, per channel, so that their mean over the view is 1, each camera weighed by its
    share of it (``shares`` (k,), default its weights' sum here): the ratios match the seams, the scale keeps the
    view as bright as the cameras (the least squares alone shrinks every gain where the overlaps' ratios disagree
    round a ring of cameras)."""
    count = len(layers)
    channels = layers[0].shape[2]
    gains = np.ones((count, channels))
    strong = weights >= GAIN_MIN_WEIGHT
    for c in range(channels):
        a = np.zeros((count, count))
        b = np.zeros(count)
        for i in range(count):
            for j in range(count):
                if i == j:
                    continue
                both = strong[i] & strong[j]
                n = float(both.sum())
                if n == 0:
                    continue
                m_ij = float(layers[i][..., c][both].mean())
                m_ji = float(layers[j][..., c][both].mean())
                a[i, i] += n * (m_ij * m_ij / GAIN_NOISE**2 + 1 / GAIN_PRIOR**2)
                a[i, j] -= n * m_ij * m_ji / GAIN_NOISE**2
                b[i] += n / GAIN_PRIOR**2
        for i in range(count):
            if a[i, i] == 0:  # no overlap: no evidence
                a[i, i], b[i] = 1.0, 1.0
        gains[:, c] = np.linalg.solve(a, b)
    share = weights.reshape(count, -1).sum(axis=1, dtype=np.float64) if shares is None else np.asarray(shares)
    if share.sum() > 0:
        gains /= (share @ gains / share.sum())[None, :]
    return gains


@dataclass(frozen=True)
class RigRemapper:
    """Applies one view of a rig to any number of its pictures (one per camera, or one frame holding them all).

    Parameters
    ----------
    rig : CameraRig
    maps : list of (H, W, 2) float32
        Each camera's map in its own picture (:func:`camera_maps`).
    interpolation : {"nearest", "linear", "cubic"}
    fill : float
        Output pixels no camera sees.
    wrap : bool
        The view's columns wrap around (feathering across the wrap).
    """

    rig: CameraRig
    maps: list[NDArray[np.float32]]
    interpolation: str = "linear"
    fill: float = 0.0
    wrap: bool = False
    seams: SeamWeights = field(init=False, repr=False)
    weights: NDArray[np.float32] = field(init=False, repr=False)
    _remappers: tuple[Remapper, ...] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        inputs.instance(self.rig, CameraRig, "the rig")
        if (
            isinstance(self.maps, np.ndarray)
            or not isinstance(self.maps, list | tuple)
            or len(self.maps) != self.rig.count
        ):
            count = len(self.maps) if isinstance(self.maps, list | tuple) else type(self.maps).__name__
            raise PanomapError(
                f"give one map per camera of the rig ({self.rig.count}; panomap.camera_maps), not {count}"
            )
        shapes = {np.shape(map_uv) for map_uv in self.maps}
        if len(shapes) != 1:
            raise PanomapError(f"the cameras' maps must have one shape (one view), not {sorted(shapes)}")
        remappers = []
        for k, (table, map_uv) in enumerate(zip(self.rig.tables, self.maps, strict=True)):
            if self.rig.offsets is None:
                remappers.append(Remapper(map_uv, table.image_size, self.interpolation, self.fill))
                continue
            x, y = self.rig.offsets[k]
            shifted = map_uv + np.array([x, y], dtype=np.float32)
            remappers.append(Remapper(shifted, self.rig.frame_size, self.interpolation, self.fill))
        object.__setattr__(self, "_remappers", tuple(remappers))
        object.__setattr__(self, "seams", seam_weights(self.maps, self.wrap))
        object.__setattr__(self, "weights", self.seams.dense())

    @property
    def output_size(self) -> tuple[int, int]:
        """(W, H) of the output."""
        return self._remappers[0].output_size

    def _sources(self, pictures: Any) -> list[NDArray[Any]]:
        """The picture each camera reads: its own, or the one frame."""
        if isinstance(pictures, np.ndarray):
            if self.rig.offsets is None and self.rig.count > 1:
                raise PanomapError(f"the rig's {self.rig.count} cameras each take their own picture: give one each")
            return [pictures] * self.rig.count
        pictures = list(pictures)
        if len(pictures) == 1 and self.rig.offsets is not None:
            return pictures * self.rig.count
        if len(pictures) != self.rig.count or self.rig.offsets is not None:
            wanted = "one frame holding them all" if self.rig.offsets is not None else f"{self.rig.count}"
            raise PanomapError(f"{len(pictures)} pictures for a rig of {self.rig.count} cameras: give {wanted}")
        return alike_pictures(pictures)

    def layers(self, pictures: Any) -> list[NDArray[Any]]:
        """Each camera's own view, unblended (the fill where it sees nothing)."""
        return [remap(source) for remap, source in zip(self._remappers, self._sources(pictures), strict=True)]

    def gains(self, pictures: Any) -> NDArray[np.float64]:
        """(k, C) gains that match the cameras over their overlaps, in these pictures."""
        return self.layer_gains(self.layers(pictures))

    def layer_gains(self, layers: list[NDArray[Any]]) -> NDArray[np.float64]:
        """:meth:`gains` of the cameras' :meth:`layers` already made."""
        return overlap_gains([_channels(layer).astype(np.float32) for layer in layers], self.weights)

    def __call__(self, pictures: Any, gains: NDArray[np.float64] | None = None) -> NDArray[Any]:
        """The blended view of ``pictures`` (one per camera in the rig's order, or one frame), each camera scaled
        by its ``gains`` ((k, C); default: found in these pictures' overlaps; ones: none)."""
        return self.blend(self.layers(pictures), gains)

    def blend(self, layers: list[NDArray[Any]], gains: NDArray[np.float64] | None = None) -> NDArray[Any]:
        """The blend of the cameras' :meth:`layers` already made (``gains`` as :meth:`__call__` takes them)."""
        dtype = layers[0].dtype
        floats = [_channels(layer).astype(np.float32) for layer in layers]
        if gains is None:
            gains = overlap_gains(floats, self.weights)
        out = np.zeros_like(floats[0])
        for layer, weight, gain in zip(floats, self.weights, gains, strict=True):
            out += layer * (weight[..., None] * gain.astype(np.float32)[None, None, :])
        out[self.weights.sum(axis=0) == 0] = self.fill
        if np.issubdtype(dtype, np.integer):
            info = np.iinfo(dtype)
            out = np.clip(np.rint(out), info.min, info.max)
        blended = out.astype(dtype)
        return blended[..., 0] if layers[0].ndim == 2 else blended


def alike_pictures(pictures: list[NDArray[Any]]) -> list[NDArray[Any]]:
    """The cameras' pictures with one number of channels: a grey (H, W) or (H, W, 1) picture beside colour ones
    is repeated into B, G and R, and a colour picture beside one with alpha gets an opaque alpha (the most
    channels any of them has). Their depths must agree: PanomapError names the two otherwise."""
    depths = sorted({picture.dtype.name for picture in pictures})
    if len(depths) > 1:
        raise PanomapError(f"the rig's pictures are of different depths ({' and '.join(depths)}): give them alike")
    channels = [_channels(picture).shape[2] for picture in pictures]
    most = max(channels)
    if min(channels) == most:
        return pictures
    if most not in (3, 4) or any(c not in (1, 3, 4) for c in channels):
        raise PanomapError(f"the rig's pictures have {min(channels)} and {most} channels: give them alike")
    return [_with_channels(picture, most) for picture in pictures]


def _with_channels(picture: NDArray[Any], channels: int) -> NDArray[Any]:
    """``picture`` (grey, BGR or BGRA) as ``channels`` (3: BGR, 4: BGRA, opaque where it had no alpha)."""
    image = _channels(picture)
    if image.shape[2] == channels:
        return image
    colour = np.repeat(image, 3, axis=2) if image.shape[2] == 1 else image[..., :3]
    if channels == 3:
        return np.ascontiguousarray(colour)
    opaque = np.iinfo(image.dtype).max if np.issubdtype(image.dtype, np.integer) else 1.0
    return np.concatenate([colour, np.full((*image.shape[:2], 1), opaque, image.dtype)], axis=2)


def _channels(image: NDArray[Any]) -> NDArray[Any]:
    """``image`` as (H, W, C)."""
    return image[..., None] if image.ndim == 2 else image
