"""From an external camera model to a pano-mapping table: each entry is its ray projected by the model.

The table's grid of world rays (theta_i, rho_j) goes through the mount (the table model's rotation R,
world to the level camera's axes), then into the calibration's frame (:mod:`.frame`), then through the
model's ``project``: affine, tangential and thin-prism terms are in the entries exactly. The table's
:class:`~panomap.camera.model.CameraModel` (what ``table.unproject`` inverts) carries the principal
point and the best radial function of the registered kinds fitted to the mean radius about it (its
largest distance from the entries is stored in ``info["import"]``: zero for a radially symmetric camera
up to that fit).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..camera.model import CameraModel
from ..camera.orientation import tilt_rotation, world_elevation_range
from ..camera.radial import RadialFunction, fit_radial
from ..camera.radial_models import MODELS
from ..errors import PanomapError
from ..geometry import TWO_PI, FloatArray
from ..table.table import PanoMappingTable, check_table_chords, check_table_rows, check_table_size
from .frame import HANDEDNESS, camera_rays
from .models.base import ExternalCamera

# Default table sizes stop here (as a fitted camera's do).
MAX_DEFAULT_SIZE = (4096, 1024)
# Azimuths over which the radius profile is averaged, and the profile's angles.
PROFILE_AZIMUTHS = 72
PROFILE_ANGLES = 2001
# A model whose image radius stops growing nearer its principal point than this (px) sees no image.
MIN_REACH_PX = 2.0
# Rows of the table projected at a time (bounds the scratch memory).
BLOCK_ROWS = 512


@dataclass(frozen=True)
class RadiusProfile:
    """The camera's mean image radius about its principal point (px) at angles from its axis (rad)."""

    alpha: FloatArray
    radius: FloatArray

    def angle_at(self, radius_px: float) -> float:
        """Angle (rad) where the mean radius reaches ``radius_px``."""
        return float(np.interp(radius_px, self.radius, self.alpha))

    def radius_at(self, alpha: FloatArray) -> FloatArray:
        return np.interp(alpha, self.alpha, self.radius)


def radius_profile(camera: ExternalCamera, max_angle_rad: float) -> RadiusProfile:
    """Mean radius over PROFILE_AZIMUTHS azimuths from the axis to ``max_angle_rad``, where it increases.

    Raises
    ------
    PanomapError
        If the camera's radius does not grow from its axis at all.
    """
    alpha = np.linspace(0.0, max_angle_rad, PROFILE_ANGLES)
    azimuth = TWO_PI * np.arange(PROFILE_AZIMUTHS) / PROFILE_AZIMUTHS
    rays = np.stack(
        [
            np.sin(alpha)[:, None] * np.cos(azimuth)[None, :],
            np.sin(alpha)[:, None] * np.sin(azimuth)[None, :],
            np.broadcast_to(np.cos(alpha)[:, None], (alpha.size, azimuth.size)),
        ],
        axis=-1,
    )
    uv = camera.project(rays) - np.asarray(camera.principal_point)
    radius = np.hypot(uv[..., 0], uv[..., 1]).mean(axis=1)
    good = np.isfinite(radius)
    with np.errstate(invalid="ignore"):  # (-inf - -inf past the model's range: NaN, not growing)
        good[1:] &= np.diff(np.where(np.isfinite(radius), radius, -np.inf)) > 0
    end = int(np.argmin(good)) if not good.all() else alpha.size
    if end < 3:
        raise PanomapError(f"the {camera.name} camera's image radius does not grow from its axis")
    return RadiusProfile(alpha[:end], radius[:end])


def radius_of_fov(camera: ExternalCamera, fov_rad: float) -> tuple[float, float]:
    """The image circle (px about the principal point) where ``camera`` sees ``fov_rad / 2`` off its axis (a lens's
    field of view across), and the angle (rad) off the axis it reaches there: ``fov_rad / 2``, or less where the
    model's image radius stops growing before it (then the radius is the model's farthest)."""
    profile = radius_profile(camera, min(math.pi, fov_rad / 2 + 0.05))
    half_rad = min(fov_rad / 2, float(profile.alpha[-1]))
    return float(profile.radius_at(np.array([half_rad]))[0]), half_rad


def model_profile(camera: ExternalCamera) -> RadiusProfile:
    """The camera's mean image radius (px) against the angle from its axis (rad), over its valid range: its
    last radius is as far from the principal point as the model runs."""
    return radius_profile(camera, float(getattr(camera, "max_angle_rad", camera.max_angle_limit_rad)))


def angle_range(
    camera: ExternalCamera,
    image_size: tuple[int, int] | None,
    cutoff_radius: float | None,
    outer_radius: float | None,
) -> tuple[tuple[float, float], tuple[float, float], RadiusProfile]:
    """The angles from the axis (rad) the table covers, its (cut-off, outer) radii (px), and the profile.

    The outer radius defaults to the model's valid range, and no further than the image's farthest
    corner when the image size is known (every pixel of the frame is in the table, as far as the
    model runs); the cut-off radius defaults to 0.
    """
    profile = model_profile(camera)
    reach = float(profile.radius[-1])
    if reach < MIN_REACH_PX:
        raise PanomapError(
            f"the {camera.name} camera's image radius stops growing {reach:.2f} px from its principal point "
            f"({math.degrees(profile.alpha[-1]):.2f} deg from the axis): its parameters make no usable camera"
        )
    if outer_radius is None:
        outer_radius = reach
        if image_size is not None:
            cx, cy = camera.principal_point
            width, height = image_size
            corner = math.hypot(max(cx + 0.5, width - 0.5 - cx), max(cy + 0.5, height - 0.5 - cy))
            outer_radius = min(reach, corner)
    cutoff_radius = 0.0 if cutoff_radius is None else float(cutoff_radius)
    if not 0 <= cutoff_radius < outer_radius:
        raise PanomapError(
            f"the cut-off radius ({cutoff_radius:g} px) must be >= 0 and below the outer radius ({outer_radius:g} px)"
        )
    if outer_radius > reach + 0.5:
        raise PanomapError(
            f"the image circle ({outer_radius:.1f} px) reaches beyond the {camera.name} model's valid range "
            f"({reach:.1f} px, {math.degrees(profile.alpha[-1]):.1f} deg from the axis)"
        )
    alphas = (profile.angle_at(cutoff_radius), profile.angle_at(min(outer_radius, reach)))
    return alphas, (cutoff_radius, float(outer_radius)), profile


def elevations_of_angles(alphas: tuple[float, float], axis: str) -> tuple[float, float]:
    """(low, high) elevations (rad) of angles (rad) from the optical axis, looking ``axis``."""
    low, high = alphas
    if axis == "down":
        return -math.pi / 2 + low, -math.pi / 2 + high
    return math.pi / 2 - high, math.pi / 2 - low


def radial_approximation(profile: RadiusProfile, alphas: tuple[float, float], axis: str) -> RadialFunction:
    """The registered radial function closest (largest error, px) to the mean radius over ``alphas``."""
    alpha = np.linspace(*alphas, 400)
    rho = -math.pi / 2 + alpha if axis == "down" else math.pi / 2 - alpha
    target = profile.radius_at(alpha)
    best: tuple[float, RadialFunction] | None = None
    for kind in MODELS:
        try:
            radial = fit_radial(kind, rho, target, axis)
        except PanomapError:
            continue
        r = radial(rho)
        if alphas[0] == 0 and abs(float(r[0])) > 1e-6:
            continue  # it must put the axis on the principal point (the paper's polynomial need not)
        increasing = np.all(np.diff(r if axis == "down" else r[::-1]) > 0)
        error = float(np.nanmax(np.abs(r - target))) if np.all(np.isfinite(r)) else math.inf
        if increasing and (best is None or error < best[0]):
            best = (error, radial)
    if best is None:
        raise PanomapError("no radial model follows the camera's radius monotonically")
    return best[1]


def project_grid(
    camera: ExternalCamera,
    model: CameraModel,
    size: tuple[int, int],
    elevation_range: tuple[float, float],
    camera_range: tuple[float, float] | None,
) -> NDArray[np.float32]:
    """Entries (M, N, 2) float32: each grid ray through the mount and the frame change into ``camera``;
    NaN where a tilted camera's ray falls outside ``camera_range`` (rad, its own elevations)."""
    m, n = size
    rho_s, rho_e = elevation_range
    rho = rho_s + np.arange(n) * (rho_e - rho_s) / n
    entries = np.empty((m, n, 2), dtype=np.float32)
    for start in range(0, m, BLOCK_ROWS):
        theta = TWO_PI * np.arange(start, min(start + BLOCK_ROWS, m)) / m
        theta_c, rho_c = model.camera_angles(theta[:, None], rho[None, :])
        uv = camera.project(camera_rays(theta_c, rho_c, model.axis, model.s, model.phi0))
        if camera_range is not None:  # a tilted camera's angles are (rows, N) arrays
            seen = (rho_c >= camera_range[0] - 1e-9) & (rho_c <= camera_range[1] + 1e-9)
            uv = np.where(seen[..., None], uv, np.nan)
        entries[start : start + theta.size] = uv
    return entries


def table_of_camera(
    camera: ExternalCamera,
    *,
    axis: str = "down",
    tilt_rad: tuple[float, float] = (0.0, 0.0),
    orientation_rad: tuple[float, float, float] | None = None,
    camera_position: tuple[float, float, float] = (0.0, 0.0, 0.0),
    image_size: tuple[int, int] | None = None,
    cutoff_radius: float | None = None,
    outer_radius: float | None = None,
    size: tuple[int, int] | None = None,
    info: dict[str, Any] | None = None,
    mirror: bool = False,
) -> PanoMappingTable:
    """The pano-mapping table of an external camera model.

    Parameters
    ----------
    camera : ExternalCamera
        The calibration's model.
    axis : {"down", "up"}
        Where the optical axis points in the world (default down: a ceiling camera).
    tilt_rad : (tilt, toward)
        The mount: the optical axis ``tilt`` rad off the vertical, leaning toward world azimuth ``toward``.
    orientation_rad : (yaw, pitch, roll), optional
        Where the camera looks, any way (rad; :mod:`panomap.camera.orientation`): the optical axis along
        yaw and pitch, the image's right turned by roll. Replaces ``axis`` and ``tilt_rad`` (give neither).
    camera_position : (X0, Y0, Z0)
        The lens centre, world units.
    image_size : (width, height), optional
        Pixels outside it are invalid; default from the calibration when it has one.
    cutoff_radius, outer_radius : float, optional
        The annulus (px about the principal point); default 0 and the model's valid range (within the
        image's farthest corner).
    size : (M, N), optional
        Default about one entry per pixel along the outer circle and along the radius.
    info : dict, optional
        Stored in the table (its ``import`` record and ``sources``).
    mirror : bool
        A mirror camera (a camera looking into a mirror): its calibration's frame, whose pixel offsets keep the
        mirror's azimuths while its image centre sees back toward the camera, is the world's mirror image, so
        the table's handedness is the opposite of a lens's (docs/conventions.md). Default: a lens.
    """
    if axis not in HANDEDNESS:
        raise PanomapError(f"axis must be 'down' or 'up', not {axis!r}")
    alphas, (cutoff, outer), profile = angle_range(camera, image_size, cutoff_radius, outer_radius)
    camera_range = elevations_of_angles(alphas, axis)
    radial = radial_approximation(profile, alphas, axis)
    tilt, toward = tilt_rad
    rotation = None
    if tilt != 0:
        matrix = tilt_rotation(tilt, toward, axis)
        rotation = tuple((float(row[0]), float(row[1]), float(row[2])) for row in matrix)
    s = -HANDEDNESS[axis] if mirror else HANDEDNESS[axis]
    model = CameraModel(camera.principal_point, radial, s, 0.0, rotation)
    if orientation_rad is not None:
        if tilt != 0 or axis != "down":
            raise PanomapError("give the orientation, or the axis and tilt, not both")
        model = model.with_orientation(*orientation_rad)
    tilted = model.rotation is not None
    world_range = world_elevation_range(camera_range, model.rotation, axis)
    if size is None:
        m = min(8 * math.ceil(TWO_PI * max(outer, 1.0) / 8), MAX_DEFAULT_SIZE[0])
        size = (max(m, 16), min(max(math.ceil(outer - cutoff), 16), MAX_DEFAULT_SIZE[1]))
    size = check_table_size(size)
    check_table_chords(size, outer)
    seen_range = camera_range if tilted else None
    check_table_rows(size, world_range, lambda grid, rows: project_grid(camera, model, grid, rows, seen_range))
    entries = project_grid(camera, model, size, world_range, seen_range)
    table_info = dict(info or {})
    record = dict(table_info.get("import", {}))
    record.update(
        {
            "model": camera.name,
            "parameters": camera.parameters(),
            "axis": axis,
            "mirror": bool(mirror),
            "radial_approximation_max_px": _approximation_error(entries, model, size, world_range),
        }
    )
    table_info["import"] = record
    return PanoMappingTable(
        entries=entries,
        elevation_range=world_range,
        model=model,
        camera_position=tuple(float(c) for c in camera_position),  # type: ignore[arg-type]
        image_size=image_size,
        cutoff_radius=cutoff,
        outer_radius=outer,
        info=table_info,
        camera_elevation_range=camera_range if tilted else None,
    )


def _approximation_error(
    entries: NDArray[np.float32],
    model: CameraModel,
    size: tuple[int, int],
    elevation_range: tuple[float, float],
) -> float:
    """Largest distance (px) between the entries and the radial model ``table.unproject`` inverts."""
    m, n = size
    step = max(1, m // 256)
    theta = TWO_PI * np.arange(0, m, step) / m
    rho = elevation_range[0] + np.arange(n) * (elevation_range[1] - elevation_range[0]) / n
    expected = model.pixels(theta[:, None], rho[None, :])
    difference = np.hypot(*np.moveaxis(expected - entries[::step], -1, 0))
    finite = difference[np.isfinite(difference)]
    return float(finite.max()) if finite.size else 0.0
