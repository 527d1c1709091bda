"""The pano-mapping table (paper 2.2, Algorithm 2): what a table is, and how it maps rays and pixels.

Convention: entry (i, j), ``i = 0..M-1`` in azimuth and ``j = 0..N-1`` in
elevation, holds the pixel (u_ij, v_ij) of the ray with
``theta_i = 2*pi*i/M`` and ``rho_j = rho_s + j*(rho_e - rho_s)/N`` (eqs. 5-8).
``entries`` has shape (M, N, 2), float32, in (u, v) order.

- :func:`fill_entries`: Algorithm 2, the entries of a camera model.
- :meth:`PanoMappingTable.sample` reads the table at any rays
  (:mod:`panomap.table.sampling`: bilinear or nearest, through ``cv2.remap``);
  :meth:`PanoMappingTable.unproject` inverts it.
- The file: :mod:`panomap.table.file` (:func:`panomap.save_table`, :func:`panomap.load_table`), which
  builds on the table (the table never imports it).

Tables are made from a fitted camera by :func:`panomap.create_table`
(:mod:`panomap.calibrate.landmarks.table`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import inputs
from ..camera.model import CameraModel
from ..errors import PanomapError
from ..geometry import TWO_PI, FloatArray, inside_image, pixel_polar, wrap_azimuth
from .sampling import MAX_TABLE_SIDE, RemapImages, remap_images, sample_entries, sample_grid

MAX_TABLE_ENTRIES = 50_000_000
# The file format's name and version (:mod:`panomap.table.file` reads versions 1 to 4). A table of a
# single-viewpoint camera is written as version 3, which panomap has read since tilted cameras; version 4
# adds the ray origins of a camera without a single viewpoint (``model["viewpoint"]``), which a reader of
# version 3 refuses by its version, saying so, rather than reading its views at the wrong distance.
TABLE_FORMAT = "panomap-table"
TABLE_VERSION = 3
VIEWPOINT_VERSION = 4
# Version 5 adds the image terms beyond the radial law (``model["terms"]``: aspect, skew, decentering), which a
# reader of version 4 would leave out of its unproject; it refuses the file by its version instead.
TERMS_VERSION = 5
# Pixels this close outside the annulus or the radial profile's ends (px) still unproject:
# the ends are solved to rounding, and a pixel's radius is computed to rounding.
PROFILE_SLACK_PX = 1e-6
# A tilted camera's table entry is kept this close (rad) outside the camera's elevation range: rounding.
CAMERA_RANGE_SLACK_RAD = 1e-9
# Newton steps of an imported table's unproject (:meth:`PanoMappingTable._refine`).
REFINE_STEPS = 6
REFINE_STEP_PX = 0.05
# ... and how close (px) its answer must sample back to the pixel (float32 entries, bilinear).
REFINE_TOLERANCE_PX = 0.01


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
    camera_elevation_range : (low, high), optional
        A tilted camera's valid elevations (rad) in its own axes (from the
        cut-off disc to the image circle): the table's (world) range reaches
        up to the tilt beyond them, and its entries there whose ray the
        camera does not see are NaN. Required when the model has a rotation,
        None otherwise.
    """

    entries: NDArray[np.float32]
    elevation_range: tuple[float, float]
    model: CameraModel
    camera_position: tuple[float, float, float]
    image_size: tuple[int, int] | None
    cutoff_radius: float
    outer_radius: float
    info: dict[str, Any] = field(default_factory=dict)
    camera_elevation_range: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        if (self.model.rotation is None) != (self.camera_elevation_range is None):
            raise PanomapError(
                "a table has a camera elevation range exactly when its camera is tilted"
                if self.model.rotation is None
                else "a tilted camera's table needs its camera elevation range"
            )
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
    def camera_range(self) -> tuple[float, float]:
        """The camera's own elevation range (rad, in its axes): ``camera_elevation_range`` for a turned camera,
        the table's range for a level one."""
        return self.camera_elevation_range if self.camera_elevation_range is not None else self.elevation_range

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
            See :mod:`panomap.table.sampling`.
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
        return sample_entries(
            self._remap_images, self.elevation_range, self.image_size, theta, rho, sampling, overwrite=overwrite
        )

    def sample_grid(self, theta: ArrayLike, rho: ArrayLike, sampling: str = "bilinear") -> NDArray[np.float32]:
        """Pixels (H, W, 2) of the rays ``theta[k]`` (W,) by ``rho[l]`` (H,): :meth:`sample` of the
        broadcast grid, value for value, without making it (a panorama's map)."""
        return sample_grid(self._remap_images, self.elevation_range, self.image_size, theta, rho, sampling)

    @cached_property
    def _remap_images(self) -> RemapImages:
        """The entries as images for ``cv2.remap`` (:func:`panomap.table.sampling.remap_images`)."""
        return remap_images(self.entries, self.image_size)

    def project(self, points: ArrayLike, sampling: str = "bilinear") -> NDArray[np.float32]:
        """Pixels (..., 2) of world points (..., 3) through the table; NaN where not visible.

        Each point is sampled at the direction of the ray that reaches it (:meth:`CameraModel.point_angles`):
        the direction from O_m, or for a camera without a single viewpoint the ray from its own origin.
        """
        d = inputs.points(points, 3, "the points") - np.asarray(self.camera_position)
        theta, rho = self.model.point_angles(d)
        return self.sample(theta, rho, sampling)

    def ray_origins(self, theta: ArrayLike, rho: ArrayLike) -> FloatArray:
        """World points (..., 3) where the rays of azimuth ``theta`` and elevation ``rho`` (rad) leave: O_m for
        a single-viewpoint camera, else each ray's own point on the axis (:mod:`panomap.camera.viewpoint`)."""
        return np.asarray(self.camera_position, dtype=np.float64) + self.model.ray_origins(theta, rho)

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
        points = inputs.points(uv, 2, "the pixels")
        theta, rho, valid = self._radial_angles(points)
        if not self.entries_from_model:
            theta, rho = self._refine(points, theta, rho)
            # A pixel the table does not reach (its ray beyond the table's range) stays unsolved: invalid.
            miss = sample_entries(self._remap_images, self.elevation_range, None, theta, rho) - points
            with np.errstate(invalid="ignore"):
                valid &= np.hypot(miss[..., 0], miss[..., 1]) <= REFINE_TOLERANCE_PX
        return np.where(valid, theta, np.nan), np.where(valid, rho, np.nan)

    def _radial_angles(self, points: FloatArray) -> tuple[FloatArray, FloatArray, NDArray[np.bool_]]:
        """theta, rho (rad) of pixels (..., 2) through the model's radial profile, and where they are valid.

        A model with image terms has them undone first; the annulus' radii are measured on the pixels so
        undone (the radial model's own radii)."""
        r, phi = pixel_polar(self.model.radial_pixels(points), self.model.centre)
        theta = np.where(r == 0, 0.0, wrap_azimuth(self.model.s * (phi - self.model.phi0)))
        rho_nodes, increasing, sign = self._radial_profile
        tilted = self.model.rotation is not None
        low, high = increasing[0], increasing[-1]
        with np.errstate(invalid="ignore"):
            slack = PROFILE_SLACK_PX
            valid = np.isfinite(r) & (r >= self.cutoff_radius - slack) & (r <= self.outer_radius + slack)
            if self.image_size is not None:
                valid &= inside_image(points[..., 0], points[..., 1], self.image_size)
            target = sign * r
            # The annulus' own edges sit on the profile's ends to rounding (they were solved for).
            valid &= (target >= low - slack) & (target <= high + slack)
        rho = np.interp(np.where(np.isfinite(target), target, low), increasing, rho_nodes)
        if tilted:
            # Those are the camera's angles: into the world's, and within the table's (world) range.
            theta, rho = self.model.world_angles(theta, rho)
            theta = np.where(np.isfinite(theta), theta, 0.0)
            with np.errstate(invalid="ignore"):
                valid &= (rho >= self.elevation_range[0] - 1e-12) & (rho <= self.elevation_range[1] + 1e-12)
        return theta, rho, valid

    @property
    def entries_from_model(self) -> bool:
        """False for a table imported from another tool's calibration (``info["import"]``): its entries
        come from that calibration's own model, and ``model`` is a radial approximation of them (its
        principal point and mean radius), which :meth:`unproject` refines against the entries."""
        return "import" not in self.info

    def _refine(self, uv: FloatArray, theta: FloatArray, rho: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Newton steps from the radial model's answer, so that :meth:`sample` of the result gives ``uv``
        back: the unknown is the model's pixel q (Cartesian, so the optical axis is no singularity), the
        table's pixel of q's ray is T(q), its Jacobian by differences of REFINE_STEP_PX."""
        q = self.model.pixels(theta, rho)
        h = REFINE_STEP_PX

        def table_pixel(q: FloatArray) -> FloatArray:
            # Read without the image's bounds: a step may cross them near the frame's edge.
            theta, rho, _ = self._radial_angles(q)
            return sample_entries(self._remap_images, self.elevation_range, None, theta, rho).astype(np.float64)

        for _ in range(REFINE_STEPS):
            t = table_pixel(q)
            du = (table_pixel(q + np.array([h, 0.0])) - t) / h
            dv = (table_pixel(q + np.array([0.0, h])) - t) / h
            f = t - uv
            det = du[..., 0] * dv[..., 1] - dv[..., 0] * du[..., 1]
            with np.errstate(invalid="ignore", divide="ignore"):
                step = np.stack(
                    [
                        (dv[..., 1] * f[..., 0] - dv[..., 0] * f[..., 1]) / det,
                        (-du[..., 1] * f[..., 0] + du[..., 0] * f[..., 1]) / det,
                    ],
                    axis=-1,
                )
            q = np.where(np.isfinite(step), q - np.clip(step, -20.0, 20.0), q)
        theta, rho, _ = self._radial_angles(q)
        return theta, rho

    @cached_property
    def _radial_profile(self) -> tuple[FloatArray, FloatArray, float]:
        """The table's radial profile as (rho nodes (N+1,), sign * r at them, sign).

        Nodes are rho_j (j < N) and rho_e; r_j = f_r(rho_j), and at rho_e the line
        through the last two entries, as bilinear sampling reads it. ``sign``
        (+1 looking down, -1 up) makes ``sign * r`` increase with rho.
        """
        radial = self.model.radial
        if self.camera_elevation_range is not None:
            # A tilted camera: its rows are no longer one radius each, so f_r itself is inverted over the
            # camera's own range.
            rho_nodes = np.linspace(*self.camera_elevation_range, 4 * self.size[1] + 1)
            radii = radial(rho_nodes)
        else:
            rho_nodes = np.append(self.elevations(), self.elevation_range[1])
            radii = radial(rho_nodes[:-1])
            radii = np.append(radii, 2 * radii[-1] - radii[-2])
        sign = 1.0 if self.model.axis == "down" else -1.0
        increasing = sign * radii
        if not (np.all(np.isfinite(increasing)) and np.all(np.diff(increasing) > 0)):
            raise PanomapError(
                f"the table's radial function ({radial.kind}) is not strictly monotonic on its elevation range"
            )
        return rho_nodes, increasing, sign

    def metadata(self) -> dict[str, Any]:
        """Everything but the entries, as JSON-ready data (angles in rad): what a table file stores beside
        them (:mod:`panomap.table.file`)."""
        m, n = self.size
        return {
            "format": TABLE_FORMAT,
            "version": TERMS_VERSION
            if self.model.terms is not None
            else (TABLE_VERSION if self.model.viewpoint is None else VIEWPOINT_VERSION),
            "size": [m, n],
            "elevation_range_rad": list(self.elevation_range),
            "model": self.model.to_dict(),
            "camera_position": list(self.camera_position),
            "image_size": None if self.image_size is None else list(self.image_size),
            "cutoff_radius_px": self.cutoff_radius,
            "outer_radius_px": self.outer_radius,
            "info": self.info,
        } | (
            {}
            if self.camera_elevation_range is None
            else {"camera_elevation_range_rad": list(self.camera_elevation_range)}
        )


def fill_entries(
    model: CameraModel,
    size: tuple[int, int],
    elevation_range: tuple[float, float],
    rows: slice = slice(None),
    camera_range: tuple[float, float] | None = None,
) -> NDArray[np.float32]:
    """Algorithm 2: entries (M, N, 2) float32 of the table of ``model``.

    ``u_ij = u0 + r_j cos(phi_i)``, ``v_ij = v0 + r_j sin(phi_i)`` with
    ``r_j = f_r(rho_j)`` and ``phi_i = s*theta_i + phi0`` (eqs. 5-8, plus the
    centre and azimuth mapping of the conventions), then the model's image terms (aspect, skew,
    decentering: :mod:`panomap.camera.image_terms`) where it keeps any; for a tilted camera, the
    world ray (theta_i, rho_j) through :meth:`CameraModel.pixels`, NaN where its
    elevation in the camera's axes is outside ``camera_range`` (rad, required
    then: the camera does not see it). ``rows`` picks azimuths
    i (the same values as those rows of the whole table).
    """
    m, n = size
    rho_s, rho_e = elevation_range
    theta = TWO_PI * np.arange(m)[rows] / m
    rho = rho_s + np.arange(n) * (rho_e - rho_s) / n
    if model.rotation is not None:
        # A tilted camera: each world ray through R into the camera's axes (no longer separable).
        if camera_range is None:
            raise PanomapError("a tilted camera's entries need its camera elevation range")
        theta_camera, rho_camera = model.camera_angles(theta[:, None], rho[None, :])
        r = model.radial(rho_camera)
        phi = model.image_angle(theta_camera)
        seen = (rho_camera >= camera_range[0] - CAMERA_RANGE_SLACK_RAD) & (
            rho_camera <= camera_range[1] + CAMERA_RANGE_SLACK_RAD
        )
        r = np.where(seen, r, np.nan)
        return model.with_terms(np.stack([r * np.cos(phi), r * np.sin(phi)], axis=-1)).astype(np.float32)
    r = model.radial(rho)
    phi = model.image_angle(theta)
    if model.terms is not None:  # aspect, skew, decentering: each entry through them (no longer separable)
        offsets = np.stack([np.cos(phi)[:, None] * r[None, :], np.sin(phi)[:, None] * r[None, :]], axis=-1)
        return model.with_terms(offsets).astype(np.float32)
    u0, v0 = model.centre
    entries = np.empty((theta.size, n, 2), dtype=np.float32)
    entries[..., 0] = u0 + np.cos(phi)[:, None] * r[None, :]
    entries[..., 1] = v0 + np.sin(phi)[:, None] * r[None, :]
    return entries


# The most a table's chords in azimuth may part from the camera's circles between its entries (px): a table
# coarser than that in azimuth (a size given) draws its views that far off, silently.
MAX_CHORD_PX = 1.0


def check_table_chords(size: tuple[int, int], radius_px: float, what: str = "table size") -> None:
    """Refuse a table of ``size`` (M, N) whose M azimuths, read bilinearly, stray from the camera's circles by
    more than :data:`MAX_CHORD_PX` between entries at ``radius_px`` (its outermost radius): a chord's sagitta,
    ``r (pi / M)^2 / 2`` (a 4 x 2 table of a 456 px circle: 140 px; its default size: under 0.001 px)."""
    m = int(size[0])
    sagitta = radius_px * (math.pi / m) ** 2 / 2
    if sagitta > MAX_CHORD_PX:
        least = math.ceil(math.pi * math.sqrt(radius_px / (2 * MAX_CHORD_PX)))
        raise PanomapError(
            f"{what} {m}x{int(size[1])}: between its {m} azimuths the views would be up to {sagitta:.0f} px off "
            f"(the image circle's radius {radius_px:.0f} px): give M >= {least} (within {MAX_CHORD_PX:g} px)"
        )


# The azimuths at which a table's rows (its elevations) are checked against the camera: enough to meet a tilted
# camera's or a model with image terms' widest row, few enough to cost nothing beside the table.
ROW_CHECK_AZIMUTHS = 16


def check_table_rows(
    size: tuple[int, int],
    elevation_range: tuple[float, float],
    grid: Callable[[tuple[int, int], tuple[float, float]], NDArray[Any]],
    what: str = "table size",
) -> None:
    """Refuse a table of ``size`` (M, N) over ``elevation_range`` (rad) whose N elevations, read between entries
    (linearly, and past the last one to the range's end as its row N extrapolates), stray from the camera's pixels
    by more than :data:`MAX_CHORD_PX`; ``grid(size, elevation_range)`` gives the entries (M', N', 2) of a table of
    any size and range, as the table's are made (the check takes :data:`ROW_CHECK_AZIMUTHS` of them, and twice the
    elevations). A hyperbolic mirror's 56 x 2 table drew its perspective views 6 px (median) to 94 px off."""
    n = int(size[1])
    error = _row_chord_px(grid, elevation_range, n)
    if error <= MAX_CHORD_PX:
        return
    low, high, worst = n, n, error
    while worst > MAX_CHORD_PX and high < MAX_TABLE_SIDE:
        low, high = high, min(2 * high, MAX_TABLE_SIDE)
        worst = _row_chord_px(grid, elevation_range, high)
    if worst > MAX_CHORD_PX:
        raise PanomapError(
            f"{what} {int(size[0])}x{n}: between its {n} elevations the views would be up to {error:.0f} px off, "
            f"still over {MAX_CHORD_PX:g} px at N = {high}: its elevations reach where the pixels run away"
        )
    while high - low > max(1, low // 64):  # (the least N, within 1.6%)
        middle = (low + high) // 2
        low, high = (low, middle) if _row_chord_px(grid, elevation_range, middle) <= MAX_CHORD_PX else (middle, high)
    raise PanomapError(
        f"{what} {int(size[0])}x{n}: between its {n} elevations the views would be up to {error:.0f} px off: give "
        f"N >= {high} (within {MAX_CHORD_PX:g} px)"
    )


def _row_chord_px(
    grid: Callable[[tuple[int, int], tuple[float, float]], NDArray[Any]], elevation_range: tuple[float, float], n: int
) -> float:
    """The farthest (px) a table of ``n`` elevations over ``elevation_range`` lies from the camera's pixels halfway
    between its entries and at the range's end (0 where no two neighbouring entries are seen)."""
    rho_s, rho_e = elevation_range
    step = (rho_e - rho_s) / (2 * n)
    fine = np.asarray(grid((ROW_CHECK_AZIMUTHS, 2 * n + 1), (rho_s, rho_e + step)), dtype=np.float64)
    entries = fine[:, 0 : 2 * n : 2]  # (the table's own, then the camera's pixels between and past them)
    last, rise = entries[:, -1:], entries[:, -1:] - entries[:, -2:-1]
    read = np.concatenate([(entries[:, :-1] + entries[:, 1:]) / 2, last + rise / 2, last + rise], axis=1)
    camera = np.concatenate([fine[:, 1 : 2 * n : 2], fine[:, 2 * n :]], axis=1)  # (halfway, halfway past, the end)
    off = np.linalg.norm(camera - read, axis=-1)
    return float(np.nanmax(off)) if np.isfinite(off).any() else 0.0


def check_table(table: Any) -> PanoMappingTable:
    """``table`` if it is a :class:`PanoMappingTable`; a TypeError saying what to pass instead (one camera of a
    rig, a loaded file) otherwise."""
    if hasattr(table, "tables") and hasattr(table, "offsets"):  # (a CameraRig, not imported: rig sits above)
        hint = ": a rig holds one table per camera (rig.tables[k]); panomap.camera_maps makes the maps of them all"
    else:
        hint = " (panomap.load_table reads a file)"
    return inputs.instance(table, PanoMappingTable, "the table", hint)


def check_table_size(size: tuple[int, int], what: str = "table size") -> tuple[int, int]:
    """Validate an (M, N) table size; ``what`` names it in the error."""
    m, n = inputs.whole_numbers(size, 2, f"the {what} (M, N)")
    if m < 4 or n < 2:
        raise PanomapError(f"{what} {m}x{n}: a table needs M >= 4 and N >= 2")
    if m * n > MAX_TABLE_ENTRIES:
        raise PanomapError(f"{what} {m}x{n}: {m * n:,} entries is more than the limit of {MAX_TABLE_ENTRIES:,}")
    if max(m, n) > MAX_TABLE_SIDE:
        raise PanomapError(f"{what} {m}x{n}: at most {MAX_TABLE_SIDE} entries a side")
    return m, n
