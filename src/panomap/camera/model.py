"""The camera model behind a pano-mapping table: centre, azimuth mapping, f_r.

Convention: ``u = u0 + r cos(phi)``, ``v = v0 + r sin(phi)``,
``phi = s*theta + phi0`` and ``r = f_r(rho)``; theta, rho in rad as in
:mod:`panomap.geometry`. The paper's assumption is ``s = +1, phi0 = 0``.

Terms beyond the radial law (:mod:`panomap.camera.image_terms`: aspect, skew, decentering, fields) move the
offset ``(u - u0, v - v0)`` of that pixel; a camera without them is rotationally symmetric.

A tilted camera (beyond the paper) has a ``rotation`` R, camera to world
(:mod:`panomap.camera.orientation`): its methods take and give **world**
angles, and apply the model above to the ray in the camera's axes, ``R.T d``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..errors import PanomapError
from ..geometry import FloatArray, azimuth_elevation, ray_from_angles
from .image_terms import ImageTerms
from .orientation import (
    orientation_of_rotation,
    rotation_of_orientation,
    tilt_angles,
    to_camera,
    to_world,
)
from .radial import RadialFunction
from .viewpoint import Viewpoint


@dataclass(frozen=True)
class CameraModel:
    """Where a ray of azimuth theta and elevation rho lands in the omni-image.

    Parameters
    ----------
    centre : (u0, v0)
        Image centre, px: where the optical axis lands.
    radial : RadialFunction
        The radial stretching function ``r = f_r(rho)``.
    s : {+1, -1}
        Handedness: -1 when the image is mirrored.
    phi0 : float
        Image angle (rad) of azimuth 0.
    rotation : (3, 3) tuple of tuples, optional
        R, camera to world, of a tilted camera; None for a level one (R = I).
    viewpoint : Viewpoint, optional
        Where each elevation's ray leaves the optical axis, for a camera without a single viewpoint
        (:mod:`panomap.camera.viewpoint`); None for a single-viewpoint camera (every ray from O_m).
    terms : ImageTerms, optional
        Aspect, skew and decentering beyond the radial law (:mod:`panomap.camera.image_terms`); None (or the
        identity) for a rotationally symmetric camera.
    """

    centre: tuple[float, float]
    radial: RadialFunction
    s: int = 1
    phi0: float = 0.0
    rotation: tuple[tuple[float, float, float], ...] | None = None
    viewpoint: Viewpoint | None = None
    terms: ImageTerms | None = None

    def __post_init__(self) -> None:
        u0, v0 = (float(c) for c in self.centre)
        if not (math.isfinite(u0) and math.isfinite(v0)):
            raise PanomapError("the image centre is not finite")
        if self.s not in (1, -1):
            raise PanomapError(f"handedness s must be +1 or -1, not {self.s!r}")
        if not math.isfinite(self.phi0):
            raise PanomapError("phi0 is not finite")
        object.__setattr__(self, "centre", (u0, v0))
        object.__setattr__(self, "s", int(self.s))
        object.__setattr__(self, "phi0", float(self.phi0))
        if self.terms is not None and self.terms.is_identity:
            object.__setattr__(self, "terms", None)
        if self.rotation is not None:
            matrix = np.asarray(self.rotation, dtype=np.float64)
            if matrix.shape != (3, 3) or not np.all(np.isfinite(matrix)):
                raise PanomapError("the camera rotation is not a finite 3 x 3 matrix")
            if not np.allclose(matrix @ matrix.T, np.eye(3), atol=1e-9) or np.linalg.det(matrix) < 0:
                raise PanomapError("the camera rotation is not a rotation (orthonormal, determinant +1)")
            level = np.allclose(matrix, np.eye(3), atol=0, rtol=0)
            rows = tuple(tuple(float(x) for x in row) for row in matrix)
            object.__setattr__(self, "rotation", None if level else rows)

    @property
    def axis(self) -> str:
        """Which pole the image centre sees: ``"down"`` (a ceiling camera) or ``"up"``.

        The radial function carries it (it is a function of the angle from
        that pole, and the table file stores it with it); read it here.
        """
        return self.radial.axis

    @property
    def tilt(self) -> tuple[float, float]:
        """(tilt_rad, toward_rad): the optical axis' angle off the vertical and the azimuth it leans toward."""
        return (0.0, 0.0) if self.rotation is None else tilt_angles(self.rotation, self.axis)

    @property
    def orientation(self) -> tuple[float, float, float]:
        """(yaw_rad, pitch_rad, roll_rad): where the camera looks, as a perspective view's yaw, pitch and roll
        (:mod:`panomap.camera.orientation`); the paper's ceiling camera is (pi/2, -pi/2, 0)."""
        return orientation_of_rotation(self.rotation, self.axis, self.s, self.phi0)

    def with_orientation(self, yaw_rad: float, pitch_rad: float, roll_rad: float) -> CameraModel:
        """This camera looking along yaw, pitch and roll (rad): its rotation R made anew (the image's
        handedness and phi0 kept), every other value the same."""
        for name, value in (("yaw", yaw_rad), ("pitch", pitch_rad), ("roll", roll_rad)):
            if not math.isfinite(value):
                raise PanomapError(f"the orientation's {name} is not finite")
        if abs(pitch_rad) > math.pi / 2 + 1e-12:
            raise PanomapError(
                f"the pitch must be between -90 and 90 deg, not {math.degrees(pitch_rad):g} deg "
                "(turn the yaw by 180 deg and the roll by 180 deg instead)"
            )
        rotation = rotation_of_orientation(yaw_rad, pitch_rad, roll_rad, self.axis, self.s, self.phi0)
        rows = tuple((float(row[0]), float(row[1]), float(row[2])) for row in rotation)
        return replace(self, rotation=rows)

    def camera_angles(self, theta: ArrayLike, rho: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Azimuth and elevation (rad) in the camera's axes of world rays at ``theta``, ``rho`` (rad)."""
        if self.rotation is None:
            return np.asarray(theta, dtype=np.float64), np.asarray(rho, dtype=np.float64)
        theta, rho = np.broadcast_arrays(np.asarray(theta, dtype=np.float64), np.asarray(rho, dtype=np.float64))
        return azimuth_elevation(to_camera(ray_from_angles(theta, rho), self.rotation))

    def world_angles(self, theta_camera: ArrayLike, rho_camera: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """World azimuth and elevation (rad) of rays at ``theta_camera``, ``rho_camera`` in the camera's axes."""
        if self.rotation is None:
            return np.asarray(theta_camera, dtype=np.float64), np.asarray(rho_camera, dtype=np.float64)
        theta, rho = np.broadcast_arrays(
            np.asarray(theta_camera, dtype=np.float64), np.asarray(rho_camera, dtype=np.float64)
        )
        return azimuth_elevation(to_world(ray_from_angles(theta, rho), self.rotation))

    @property
    def single_viewpoint(self) -> bool:
        """Every ray leaves from O_m (no :class:`Viewpoint`)."""
        return self.viewpoint is None

    def axis_direction(self) -> FloatArray:
        """The camera's Z axis in world axes (3,): the line the ray origins of a non-central camera lie on."""
        if self.rotation is None:
            return np.array([0.0, 0.0, 1.0])
        return np.asarray(self.rotation, dtype=np.float64)[:, 2].copy()

    def point_angles(self, d: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """World azimuth and elevation (rad) of the rays that reach points ``d`` (..., 3), relative to O_m.

        The direction from O_m for a single-viewpoint camera; otherwise the direction of the ray, leaving the
        axis at its own point (:mod:`panomap.camera.viewpoint`), that passes through the point: the table
        entry where the point is seen.
        """
        d = np.asarray(d, dtype=np.float64)
        if self.viewpoint is None:
            return azimuth_elevation(d)
        camera = to_camera(d, self.rotation)
        theta = np.arctan2(camera[..., 1], camera[..., 0])
        rho = self.viewpoint.elevation_of_point(np.hypot(camera[..., 0], camera[..., 1]), camera[..., 2])
        return self.world_angles(theta, rho)

    def ray_origins(self, theta: ArrayLike, rho: ArrayLike) -> FloatArray:
        """Where the rays of world azimuth ``theta`` and elevation ``rho`` (rad) leave, (..., 3) relative to
        O_m in world axes: zero for a single-viewpoint camera."""
        theta, rho = np.broadcast_arrays(np.asarray(theta, dtype=np.float64), np.asarray(rho, dtype=np.float64))
        if self.viewpoint is None:
            return np.zeros((*theta.shape, 3))
        _, rho_camera = self.camera_angles(theta, rho)
        return self.viewpoint.offset(rho_camera)[..., None] * self.axis_direction()

    def image_angle(self, theta: ArrayLike) -> FloatArray:
        """Image angle phi (rad) of azimuth(s) theta (rad) in the camera's axes."""
        return self.s * np.asarray(theta, dtype=np.float64) + self.phi0

    def pixels(self, theta: ArrayLike, rho: ArrayLike) -> FloatArray:
        """Pixels (..., 2) of world rays with azimuth ``theta`` and elevation ``rho`` (rad)."""
        theta, rho = self.camera_angles(theta, rho)
        r = self.radial(rho)
        phi = self.image_angle(theta)
        return self.with_terms(np.stack([r * np.cos(phi), r * np.sin(phi)], axis=-1))

    def with_terms(self, offsets: ArrayLike) -> FloatArray:
        """Pixels (..., 2) of the radial model's offsets (..., 2) px from the centre, through the terms."""
        offsets = np.asarray(offsets, dtype=np.float64)
        moved = offsets if self.terms is None else self.terms.apply(offsets)
        return moved + np.asarray(self.centre)

    def radial_pixels(self, uv: ArrayLike) -> FloatArray:
        """Pixels (..., 2) with the terms undone: where the rotationally symmetric model puts each pixel's ray
        (the pixels themselves without terms; NaN where the terms cannot be undone)."""
        uv = np.asarray(uv, dtype=np.float64)
        if self.terms is None:
            return uv
        centre = np.asarray(self.centre)
        return self.terms.undo(uv - centre) + centre

    def to_dict(self) -> dict[str, Any]:
        """Plain data; ``rotation`` (rows of R) only for a tilted camera, ``terms`` only where kept."""
        data: dict[str, Any] = {
            "centre": list(self.centre),
            "s": self.s,
            "phi0_rad": self.phi0,
            "radial": self.radial.to_dict(),
        }
        if self.rotation is not None:
            data["rotation"] = [list(row) for row in self.rotation]
        if self.viewpoint is not None:
            data["viewpoint"] = self.viewpoint.to_dict()
        if self.terms is not None:
            data["terms"] = self.terms.to_dict()
        return data

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> CameraModel:
        try:
            u0, v0 = data["centre"]
            rotation = data.get("rotation")
            if rotation is not None:
                rotation = tuple(tuple(float(x) for x in row) for row in rotation)
            viewpoint = None if data.get("viewpoint") is None else Viewpoint.from_dict(data["viewpoint"])
            terms = None if data.get("terms") is None else ImageTerms.from_dict(data["terms"])
            return cls(
                (u0, v0),
                RadialFunction.from_dict(data["radial"]),
                int(data["s"]),
                float(data["phi0_rad"]),
                rotation,
                viewpoint,
                terms,
            )
        except (KeyError, TypeError, ValueError) as exc:
            if isinstance(exc, PanomapError):
                raise
            raise PanomapError(f"camera model is malformed ({exc})") from None
