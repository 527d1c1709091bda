"""The pano-mapping table (paper 2.2, Algorithm 2): creation, sampling and its file.

Convention: entry (i, j), ``i = 0..M-1`` in azimuth and ``j = 0..N-1`` in
elevation, holds the pixel (u_ij, v_ij) of the ray with
``theta_i = 2*pi*i/M`` and ``rho_j = rho_s + j*(rho_e - rho_s)/N`` (eqs. 5-8).
``entries`` has shape (M, N, 2), float32, in (u, v) order.

Sampling at fractional indices ``fi = theta*M/(2*pi)``,
``fj = (rho - rho_s)*N/(rho_e - rho_s)``:

- ``bilinear`` (default): linear in both, wrapping in azimuth. The table has no
  entry at rho_e itself, so the last cell [rho_{N-1}, rho_e] continues the
  line through the last two entries.
- ``nearest``: floor indices, exactly the paper's eqs. (9), (12), (19), (22).

Rays outside [rho_s, rho_e], or landing outside the image, get NaN.

The sampling itself is ``cv2.remap`` over the entries laid out as two float32
images (u and v), padded with the azimuth wrap and the extrapolated last cell.
OpenCV 5 interpolates 1-, 3- and 4-channel float32 images with exact float
weights (older versions, and 2-channel images, use 1/32 steps), so the result
is the bilinear interpolation of the entries in float32 arithmetic: within
1.5e-4 px of a float64 evaluation for coordinates below 1024 px, 3e-4 px below
2048 px (about two float32 steps). Indices are computed in the angles'
precision (float32 angles give float32 indices).
:meth:`PanoMappingTable.unproject` inverts the table.

File: a NumPy ``.npz`` holding ``entries`` and ``meta`` (JSON text with
``format = "panomap-table"``, ``version``, the model, the elevation range,
radii, image size, camera position, the landmarks and the fit report, and the
SHA-256 of ``entries``). Loading checks all of it and that the entries are
what the model gives.
"""

from __future__ import annotations

import hashlib
import json
import math
import zipfile
from dataclasses import dataclass, field
from functools import cache, cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Any

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..camera.model import CameraModel
from ..camera.radial import radius_standard_error, valid_elevation_range
from ..errors import PanomapError
from ..files import write_with
from ..geometry import TWO_PI, FloatArray, azimuth_elevation, wrap_azimuth

if TYPE_CHECKING:
    from ..calibrate.fit import CameraFit

TABLE_FORMAT = "panomap-table"
TABLE_VERSION = 1
SAMPLINGS = ("bilinear", "nearest")
MAX_TABLE_ENTRIES = 50_000_000
# cv2.remap takes images and maps below 32767 px a side; the padded table must fit.
MAX_TABLE_SIDE = 32_000
# Default sizes stop here: bilinear sampling is then within 1e-3 px of the model.
DEFAULT_MAX_SIZE = (4096, 1024)
# Entries are float32: about 1e-4 px at radii of 2000 px. A loaded table whose
# entries stray further than this from its own model is corrupt.
ENTRY_TOLERANCE_PX = 1e-2
# A row index that reads only the NaN border of the sampling images (invalid pixels go there).
OUTSIDE = -4.0
# Pixels this close outside the annulus or the radial profile's ends (px) still unproject:
# the ends are solved to rounding, and a pixel's radius is computed to rounding.
PROFILE_SLACK_PX = 1e-6


@dataclass(frozen=True)
class PanoMappingTable:
    """An M x N pano-mapping table and what it was made from.

    Parameters
    ----------
    entries : (M, N, 2) float32 ndarray
        Pixel (u, v) of entry (i, j).
    elevation_range : (rho_s, rho_e)
        Elevations (rad) of the table's first row and of the end of its last.
    model : CameraModel
        The fitted model the entries were filled from.
    camera_position : (X0, Y0, Z0)
        O_m in world units.
    image_size : (width, height) or None
        Size of the omni-images this table is for.
    cutoff_radius, outer_radius : float
        The visible annulus, px.
    info : dict
        Provenance (where the centre and radii came from) and the fit report.
    """

    entries: NDArray[np.float32]
    elevation_range: tuple[float, float]
    model: CameraModel
    camera_position: tuple[float, float, float]
    image_size: tuple[int, int] | None
    cutoff_radius: float
    outer_radius: float
    info: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        entries = np.ascontiguousarray(self.entries, dtype=np.float32)
        if entries.ndim != 3 or entries.shape[2] != 2 or entries.shape[0] < 2 or entries.shape[1] < 2:
            raise PanomapError(f"table entries must have shape (M, N, 2) with M, N >= 2, not {entries.shape}")
        rho_s, rho_e = (float(x) for x in self.elevation_range)
        if not (-math.pi / 2 - 1e-9 <= rho_s < rho_e <= math.pi / 2 + 1e-9):
            raise PanomapError(f"table elevation range {rho_s}..{rho_e} rad is not an interval in [-pi/2, pi/2]")
        if max(entries.shape[:2]) > MAX_TABLE_SIDE:
            raise PanomapError(
                f"table size {entries.shape[0]}x{entries.shape[1]}: at most {MAX_TABLE_SIDE} entries a side"
            )
        entries.setflags(write=False)
        object.__setattr__(self, "entries", entries)
        object.__setattr__(self, "elevation_range", (rho_s, rho_e))

    @property
    def size(self) -> tuple[int, int]:
        """(M, N): entries in azimuth and in elevation."""
        return int(self.entries.shape[0]), int(self.entries.shape[1])

    def azimuths(self) -> FloatArray:
        """theta_i = 2*pi*i/M (rad), eq. (5); shape (M,)."""
        m = self.size[0]
        return TWO_PI * np.arange(m) / m

    def elevations(self) -> FloatArray:
        """rho_j = rho_s + j*(rho_e - rho_s)/N (rad), eq. (6); shape (N,)."""
        n = self.size[1]
        rho_s, rho_e = self.elevation_range
        return rho_s + np.arange(n) * (rho_e - rho_s) / n

    def sample(
        self, theta: ArrayLike, rho: ArrayLike, sampling: str = "bilinear", *, overwrite: bool = False
    ) -> NDArray[np.float32]:
        """Pixels of rays, read from the table.

        Parameters
        ----------
        theta, rho : (...) array_like
            Azimuth and elevation (rad), broadcast together. Any azimuth wraps.
            float32 inputs are indexed in float32 (for maps, where speed
            matters), anything else in float64.
        sampling : {"bilinear", "nearest"}
            See the module docstring.
        overwrite : bool
            Let the method use ``theta`` and ``rho`` as its scratch memory when
            they are (H, W) float32 arrays of their own (saves two allocations
            for maps); their contents are then lost.

        Returns
        -------
        (..., 2) float32 ndarray
            Pixel (u, v); NaN where ``rho`` is outside the table's range, the
            ray is NaN, or the pixel falls outside the image.
        """
        if sampling not in SAMPLINGS:
            raise PanomapError(f"table sampling must be bilinear or nearest, not {sampling!r}")
        theta_in, rho_in = np.broadcast_arrays(np.asarray(theta), np.asarray(rho))
        dtype = np.float32 if theta_in.dtype == np.float32 and rho_in.dtype == np.float32 else np.float64
        shape = theta_in.shape
        count = theta_in.size
        if count == 0:
            return np.empty((*shape, 2), dtype=np.float32)
        m, n = self.size
        rho_s, rho_e = self.elevation_range
        rows, cols = _remap_grid(shape)
        reuse = (
            overwrite
            and dtype == np.float32
            and (rows, cols) == shape
            and all(isinstance(a, np.ndarray) and a.flags.c_contiguous and a.flags.writeable for a in (theta, rho))
            and not np.may_share_memory(theta, rho)
        )
        fi_flat: NDArray[np.floating[Any]]
        fj_flat: NDArray[np.floating[Any]]
        if reuse:
            fi_flat, fj_flat = np.asarray(theta).reshape(-1), np.asarray(rho).reshape(-1)
        else:
            fi_flat, fj_flat = np.empty(rows * cols, dtype), np.empty(rows * cols, dtype)
        fi = fi_flat[:count].reshape(shape)
        fj = fj_flat[:count].reshape(shape)
        np.multiply(theta_in, m / TWO_PI, out=fi, casting="unsafe")
        np.subtract(rho_in, rho_s, out=fj, casting="unsafe")
        fj *= n / (rho_e - rho_s)
        fi_flat[count:] = 0.0
        fj_flat[count:] = OUTSIDE
        with np.errstate(invalid="ignore"):
            # The padded images hold columns M..M+2 (= 0..2): indices up to M + 1 need no wrapping.
            # NaN anywhere makes these comparisons false, and the careful path below runs.
            plain = bool(fi_flat.min() >= 0) and bool(fi_flat.max() <= m + 1)
            highest = fj_flat.max()
            plain &= bool(np.isfinite(fj_flat.min())) and bool(np.isfinite(highest))
            if plain:
                # Below rho_s the reads reach the NaN border by themselves; beyond rho_e they must be sent there.
                if highest > n:
                    np.copyto(fj_flat, OUTSIDE, where=fj_flat > n)
            else:
                fi_flat -= m * np.floor(fi_flat / m)
                invalid = ~((fj_flat >= 0) & (fj_flat <= n) & np.isfinite(fi_flat))
                np.copyto(fi_flat, 0.0, where=invalid)
                np.copyto(fj_flat, OUTSIDE, where=invalid)
        u_image, v_image, all_inside = self._remap_images
        if sampling == "nearest":
            np.floor(fi_flat, out=fi_flat)
            np.floor(fj_flat, out=fj_flat)
            np.minimum(fj_flat, n - 1, out=fj_flat)
            interpolation = cv2.INTER_NEAREST
        else:
            interpolation = cv2.INTER_LINEAR
        map_x = fi_flat.astype(np.float32, copy=False).reshape(rows, cols)
        map_y = fj_flat.astype(np.float32, copy=False).reshape(rows, cols)
        u = cv2.remap(u_image, map_x, map_y, interpolation, borderMode=cv2.BORDER_CONSTANT, borderValue=math.nan)
        v = cv2.remap(v_image, map_x, map_y, interpolation, borderMode=cv2.BORDER_CONSTANT, borderValue=math.nan)
        uv = cv2.merge([u, v])
        if not all_inside and self.image_size is not None:
            width, height = self.image_size
            inside = cv2.inRange(uv, (-0.5, -0.5), (width - 0.5, height - 0.5))
            uv[inside == 0] = np.nan
        return np.asarray(uv.reshape(-1, 2)[:count].reshape(*shape, 2), dtype=np.float32)

    @cached_property
    def _remap_images(self) -> tuple[NDArray[np.float32], NDArray[np.float32], bool]:
        """The entries as (N + 2, M + 3) float32 u and v images for ``cv2.remap``.

        Row j, column i holds entry (i, j): azimuth runs along the rows, as it
        does along most views' rows, which keeps reads close together. Columns
        M..M+2 repeat columns 0..2 (the azimuth wrap); row N continues the
        line through the last two entries (the last cell reaches rho_e) and
        row N+1 repeats it, so every read of a valid index is finite. Also
        says whether every value lies inside the image, when the bounds check
        can be skipped.
        """
        _check_exact_remap()
        m, n = self.size
        u_image = np.empty((n + 2, m + 3), dtype=np.float32)
        v_image = np.empty((n + 2, m + 3), dtype=np.float32)
        transposed = cv2.transpose(np.ascontiguousarray(self.entries))  # (N, M, 2), cache-blocked
        for channel, image in enumerate((u_image, v_image)):
            image[:n, :m] = transposed[..., channel]
            image[:n, m:] = image[:n, np.arange(3) % m]
            # 2a - b of float32 values is exact in float64, so float32 arithmetic rounds it the same way.
            image[n] = 2 * image[n - 1] - image[n - 2]
            image[n + 1] = image[n]
        all_inside = True
        if self.image_size is not None:
            width, height = self.image_size
            all_inside = bool(
                u_image.min() >= -0.5
                and u_image.max() <= width - 0.5
                and v_image.min() >= -0.5
                and v_image.max() <= height - 0.5
            )
        for image in (u_image, v_image):
            image.setflags(write=False)
        return u_image, v_image, all_inside

    def project(self, points: ArrayLike, sampling: str = "bilinear") -> NDArray[np.float32]:
        """Pixels (..., 2) of world points (..., 3) through the table; NaN where not visible."""
        d = np.asarray(points, dtype=np.float64) - np.asarray(self.camera_position)
        theta, rho = azimuth_elevation(d)
        return self.sample(theta, rho, sampling)

    def unproject(self, uv: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Azimuth and elevation of pixels: the inverse of the table.

        The table is filled from its model, ``u = u0 + f_r(rho) cos(s*theta + phi0)``,
        ``v = v0 + f_r(rho) sin(s*theta + phi0)``, and read bilinearly. So:
        ``theta = s*(phi - phi0)`` from the image angle ``phi = atan2(v - v0, u - u0)``,
        and ``rho`` inverts the table's radial profile, ``r_j = f_r(rho_j)`` at the
        table's elevations joined linearly as sampling joins them (the last cell
        continuing the line to rho_e). f_r must be strictly monotonic there, which
        makes the inverse exact and unique. :meth:`sample` of the result gives the
        pixel back within 1e-3 px (what is left is the table's chords in azimuth,
        ``r (pi/M)^2 / 2``, and float32); inverting f_r itself would differ from
        that by the table's interpolation error, up to ``f_r'' drho^2`` in the last
        cell (0.02 px at the rim of an 800 px hyperbolic mirror image).

        Convention: pixel centres at integers, (0, 0) the top-left one; the image
        centre itself (r = 0, when inside the range) gets azimuth 0, as a vertical
        ray does in :func:`~panomap.geometry.azimuth_elevation`.

        Parameters
        ----------
        uv : (..., 2) array_like
            Pixels (u, v).

        Returns
        -------
        theta : (...) ndarray
            Azimuth (rad) in [0, 2*pi).
        rho : (...) ndarray
            Elevation (rad) in [rho_s, rho_e].
            Both NaN outside the valid region: inside the cut-off radius, beyond
            the outer radius, beyond the table's elevation range, or outside the
            image.

        Raises
        ------
        PanomapError
            If f_r is not strictly monotonic over the table's elevations.
        """
        points = np.asarray(uv, dtype=np.float64)
        if points.ndim == 0 or points.shape[-1] != 2:
            raise PanomapError(f"pixels must have shape (..., 2), not {points.shape}")
        u0, v0 = self.model.centre
        du = points[..., 0] - u0
        dv = points[..., 1] - v0
        r = np.hypot(du, dv)
        theta = np.where(r == 0, 0.0, wrap_azimuth(self.model.s * (np.arctan2(dv, du) - self.model.phi0)))
        rho_nodes, increasing, sign = self._radial_profile
        low, high = increasing[0], increasing[-1]
        with np.errstate(invalid="ignore"):
            slack = PROFILE_SLACK_PX
            valid = np.isfinite(r) & (r >= self.cutoff_radius - slack) & (r <= self.outer_radius + slack)
            if self.image_size is not None:
                width, height = self.image_size
                valid &= (points[..., 0] >= -0.5) & (points[..., 0] <= width - 0.5)
                valid &= (points[..., 1] >= -0.5) & (points[..., 1] <= height - 0.5)
            target = sign * r
            # The annulus' own edges sit on the profile's ends to rounding (they were solved for).
            valid &= (target >= low - slack) & (target <= high + slack)
        rho = np.interp(np.where(valid, target, low), increasing, rho_nodes)
        return np.where(valid, theta, np.nan), np.where(valid, rho, np.nan)

    @cached_property
    def _radial_profile(self) -> tuple[FloatArray, FloatArray, float]:
        """The table's radial profile as (rho nodes (N+1,), sign * r at them, sign).

        Nodes are rho_j (j < N) and rho_e; r_j = f_r(rho_j), and at rho_e the line
        through the last two entries, as bilinear sampling reads it. ``sign``
        (+1 looking down, -1 up) makes ``sign * r`` increase with rho.
        """
        radial = self.model.radial
        rho_nodes = np.append(self.elevations(), self.elevation_range[1])
        radii = radial(rho_nodes[:-1])
        radii = np.append(radii, 2 * radii[-1] - radii[-2])
        sign = 1.0 if radial.axis == "down" else -1.0
        increasing = sign * radii
        if not (np.all(np.isfinite(increasing)) and np.all(np.diff(increasing) > 0)):
            raise PanomapError(
                f"the table's radial function ({radial.kind}) is not strictly monotonic on its elevation range"
            )
        return rho_nodes, increasing, sign

    def metadata(self) -> dict[str, Any]:
        """Everything but the entries, as JSON-ready data (angles in rad)."""
        m, n = self.size
        return {
            "format": TABLE_FORMAT,
            "version": TABLE_VERSION,
            "size": [m, n],
            "elevation_range_rad": list(self.elevation_range),
            "model": self.model.to_dict(),
            "camera_position": list(self.camera_position),
            "image_size": None if self.image_size is None else list(self.image_size),
            "cutoff_radius_px": self.cutoff_radius,
            "outer_radius_px": self.outer_radius,
            "info": self.info,
        }

    def save(self, path: str | Path) -> None:
        """Write the table to ``path`` (an ``.npz``), through a temporary file."""
        meta = self.metadata() | {"entries_sha256": _digest(self.entries)}
        text = json.dumps(meta, indent=1, allow_nan=False)

        def writer(handle: Any) -> None:
            np.savez(handle, entries=self.entries, meta=np.array(text))

        write_with(path, writer)


def _remap_grid(shape: tuple[int, ...]) -> tuple[int, int]:
    """(rows, cols) to lay ``shape``'s elements out for ``cv2.remap`` (below 32767 a side)."""
    if len(shape) == 2 and 0 < shape[0] < MAX_TABLE_SIDE and 0 < shape[1] < MAX_TABLE_SIDE:
        return shape[0], shape[1]
    count = math.prod(shape)
    cols = min(count, 16_384)
    return -(-count // cols), cols


@cache
def _check_exact_remap() -> None:
    """Refuse an OpenCV whose ``remap`` interpolates float32 images in 1/32 steps (before 5.0)."""
    image = np.array([[0.0, 1000.0], [0.0, 1000.0]], dtype=np.float32)
    at = np.full((1, 1), 0.3, dtype=np.float32)
    value = float(cv2.remap(image, at, np.zeros_like(at), cv2.INTER_LINEAR)[0, 0])
    if abs(value - 300.0) > 1e-3:
        raise PanomapError(
            f"OpenCV {cv2.__version__} interpolates float images in 1/32-pixel steps; panomap needs OpenCV >= 5.0"
        )


def fill_entries(
    model: CameraModel, size: tuple[int, int], elevation_range: tuple[float, float], rows: slice = slice(None)
) -> NDArray[np.float32]:
    """Algorithm 2: entries (M, N, 2) float32 of the table of ``model``.

    ``u_ij = u0 + r_j cos(phi_i)``, ``v_ij = v0 + r_j sin(phi_i)`` with
    ``r_j = f_r(rho_j)`` and ``phi_i = s*theta_i + phi0`` (eqs. 5-8, plus the
    centre and azimuth mapping of the conventions). ``rows`` picks azimuths
    i (the same values as those rows of the whole table).
    """
    m, n = size
    rho_s, rho_e = elevation_range
    theta = TWO_PI * np.arange(m)[rows] / m
    rho = rho_s + np.arange(n) * (rho_e - rho_s) / n
    r = model.radial(rho)
    phi = model.image_angle(theta)
    u0, v0 = model.centre
    entries = np.empty((theta.size, n, 2), dtype=np.float32)
    entries[..., 0] = u0 + np.cos(phi)[:, None] * r[None, :]
    entries[..., 1] = v0 + np.sin(phi)[:, None] * r[None, :]
    return entries


def check_table_size(size: tuple[int, int], what: str = "--size") -> tuple[int, int]:
    """Validate an (M, N) table size."""
    m, n = (int(x) for x in size)
    if m < 4 or n < 2:
        raise PanomapError(f"{what} {m}x{n}: a table needs M >= 4 and N >= 2")
    if m * n > MAX_TABLE_ENTRIES:
        raise PanomapError(f"{what} {m}x{n}: {m * n:,} entries is more than the limit of {MAX_TABLE_ENTRIES:,}")
    if max(m, n) > MAX_TABLE_SIDE:
        raise PanomapError(f"{what} {m}x{n}: at most {MAX_TABLE_SIDE} entries a side")
    return m, n


def create_table(
    fit: CameraFit,
    *,
    size: tuple[int, int] | None = None,
    image_size: tuple[int, int] | None = None,
    cutoff_radius: float | None = None,
    outer_radius: float | None = None,
    info: dict[str, Any] | None = None,
) -> PanoMappingTable:
    """Make the pano-mapping table of a fitted camera.

    Parameters
    ----------
    fit : CameraFit
        The landmark fit.
    size : (M, N), optional
        Default: about one entry per pixel along the image circle (M) and
        along the radius (N).
    image_size : (width, height), optional
        The omni-images' size; limits the default outer radius and marks
        pixels outside the image invalid.
    cutoff_radius : float, optional
        Radius (px) of the self-occlusion disc; default 0 (none).
    outer_radius : float, optional
        Radius (px) of the image circle; default the largest circle about the
        centre inside the image (or reaching the farthest landmark, if that is
        further), or the farthest landmark when there is no image size.

    The elevation range runs from the cut-off radius to the outer radius,
    narrowed to where f_r is monotonic and around the landmarks.
    """
    u0, v0 = fit.model.centre
    r_landmarks = np.hypot(fit.landmarks.pixels[:, 0] - u0, fit.landmarks.pixels[:, 1] - v0)
    sources = dict(info.get("sources", {})) if info else {}
    if cutoff_radius is None:
        cutoff_radius = 0.0
        sources.setdefault("cutoff_radius", "default (none)")
    else:
        sources.setdefault("cutoff_radius", "given")
    if outer_radius is None:
        if image_size is not None:
            width, height = image_size
            inscribed = min(u0 + 0.5, v0 + 0.5, width - 0.5 - u0, height - 0.5 - v0)
            outer_radius = max(float(inscribed), float(r_landmarks.max()))
            sources.setdefault("outer_radius", "default (largest circle inside the image)")
        else:
            outer_radius = float(r_landmarks.max())
            sources.setdefault("outer_radius", "default (farthest landmark)")
    else:
        sources.setdefault("outer_radius", "given")
    cutoff_radius, outer_radius = float(cutoff_radius), float(outer_radius)
    if not (math.isfinite(cutoff_radius) and math.isfinite(outer_radius)) or not 0 <= cutoff_radius < outer_radius:
        raise PanomapError(
            f"the cut-off radius ({cutoff_radius:g} px) must be >= 0 and below the outer radius ({outer_radius:g} px)"
        )
    known = [name for name in ("cutoff_radius", "outer_radius") if not sources[name].startswith("default")]
    if known:
        from ..calibrate.fit import annulus_coverage_problem  # (fitting code, not needed to read a table)

        problem = annulus_coverage_problem(fit.model.radial, fit.landmark_range, cutoff_radius, outer_radius)
        if problem:
            raise PanomapError(
                f"the fitted radial function ({fit.model.radial.kind}) {problem}; it must run monotonically "
                "from the cut-off radius to the image circle (try another --model, or check the radii)"
            )
    rho_s, rho_e = valid_elevation_range(fit.model.radial, fit.landmark_range, cutoff_radius, outer_radius)
    if size is None:
        r_span = abs(float(fit.model.radial(rho_e) - fit.model.radial(rho_s)))
        reach = max(float(np.nanmax(np.abs(fit.model.radial(np.array([rho_s, rho_e]))))), 1.0)
        m = min(8 * math.ceil(TWO_PI * reach / 8), DEFAULT_MAX_SIZE[0])
        size = (max(m, 16), min(max(math.ceil(r_span), 16), DEFAULT_MAX_SIZE[1]))
    size = check_table_size(size)
    entries = fill_entries(fit.model, size, (rho_s, rho_e))
    table_info = dict(info or {})
    table_info["sources"] = sources
    table_info["fit"] = fit.report().to_dict() | {"uncertainty": _uncertainty(fit, (rho_s, rho_e))}
    table_info["warnings"] = _range_warnings(fit.landmark_range, (rho_s, rho_e))
    return PanoMappingTable(
        entries=entries,
        elevation_range=(rho_s, rho_e),
        model=fit.model,
        camera_position=fit.camera_position,
        image_size=image_size,
        cutoff_radius=cutoff_radius,
        outer_radius=outer_radius,
        info=table_info,
    )


# The table may reach this far beyond the landmarks' elevations before a warning says so.
EXTRAPOLATION_WARNING_DEG = 3.0


def _uncertainty(fit: CameraFit, elevation_range: tuple[float, float]) -> dict[str, Any]:
    """Standard error of f_r (px) on a grid over the table's range, and its summary."""
    rho = np.linspace(*elevation_range, 91)
    se = radius_standard_error(fit.model.radial, fit.covariance, rho)
    low, high = fit.landmark_range
    inside = (rho >= low) & (rho <= high)
    return {
        "elevation_deg": np.degrees(rho).tolist(),
        "radius_se_px": se.tolist(),
        "max_se_in_landmark_range_px": float(se[inside].max()) if inside.any() else None,
        "max_se_px": float(se.max()),
    }


def _range_warnings(landmark_range: tuple[float, float], table_range: tuple[float, float]) -> list[str]:
    """Warnings where the table reaches beyond the landmarks' elevations by more than a few degrees."""
    warnings = []
    below = math.degrees(landmark_range[0] - table_range[0])
    above = math.degrees(table_range[1] - landmark_range[1])
    if below > EXTRAPOLATION_WARNING_DEG:
        warnings.append(
            f"the table reaches {below:.1f} deg below the lowest landmark "
            f"({math.degrees(landmark_range[0]):.1f} deg): the radius there is extrapolated"
        )
    if above > EXTRAPOLATION_WARNING_DEG:
        warnings.append(
            f"the table reaches {above:.1f} deg above the highest landmark "
            f"({math.degrees(landmark_range[1]):.1f} deg): the radius there is extrapolated"
        )
    return warnings


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
