"""Landmark learning (paper 2.1, Algorithm 1): from landmark pairs to a camera model.

Convention: world Z up; a landmark's ray is ``d = P - O_m``; azimuth and
elevation as in :mod:`panomap.geometry`; pixel radius and image angle about
the given image centre (u0, v0).

Beyond the paper, the fit also estimates the azimuth mapping
``phi = s*theta + phi0`` (the paper assumes ``s = +1, phi0 = 0``; pass
``azimuth="paper"`` to keep that), finds whether the camera looks down or up,
and chooses the radial model by leave-one-out cross-validation unless one is
forced (``model="paper"`` is Algorithm 1 exactly).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import stats

from .errors import PanomapError
from .geometry import FloatArray, azimuth_elevation
from .landmarks import MIN_LANDMARKS, Landmarks
from .model import CameraModel
from .radial import AUTO_CANDIDATES, AXES, MODELS, fit_radial, is_monotonic, leave_one_out_rms

MIN_ELEVATION_SPREAD = math.radians(1.0)
AZIMUTH_MODES = ("fit", "paper")


@dataclass(frozen=True)
class CameraFit:
    """A fitted camera model with the fit report.

    Attributes
    ----------
    model : CameraModel
    theta, rho : (n,) ndarray
        Landmark azimuths and elevations (rad).
    predicted : (n, 2) ndarray
        Where the model puts each landmark, px.
    residuals_px : (n,) ndarray
        Distance (px) between each landmark's pixel and its prediction.
    radial_residuals_px : (n,) ndarray
        Fitted minus measured radius, px.
    axis_source : str
        ``"given"`` or ``"detected"``.
    azimuth_mode : str
        ``"fit"`` (s and phi0 estimated) or ``"paper"`` (s = +1, phi0 = 0).
    azimuth_consistency : float
        Weighted mean resultant length (0..1) of ``phi - s*theta``: 1 when
        every landmark agrees on phi0.
    selection : dict
        Leave-one-out RMS (px) of each candidate radial model tried.
    """

    model: CameraModel
    landmarks: Landmarks
    camera_position: tuple[float, float, float]
    theta: FloatArray
    rho: FloatArray
    predicted: FloatArray
    residuals_px: FloatArray
    radial_residuals_px: FloatArray
    axis_source: str
    azimuth_mode: str
    azimuth_consistency: float
    selection: dict[str, float] = field(default_factory=dict)

    @property
    def rms_px(self) -> float:
        return float(np.sqrt(np.mean(self.residuals_px**2)))

    @property
    def max_px(self) -> float:
        return float(np.max(self.residuals_px))

    @property
    def landmark_range(self) -> tuple[float, float]:
        """Lowest and highest landmark elevation (rad)."""
        return float(np.min(self.rho)), float(np.max(self.rho))

    def report(self) -> dict[str, Any]:
        """The fit report as plain data (angles in degrees, residuals in px)."""
        rows = []
        for k, record in enumerate(self.landmarks.to_records()):
            rows.append(
                record
                | {
                    "azimuth_deg": math.degrees(float(self.theta[k])),
                    "elevation_deg": math.degrees(float(self.rho[k])),
                    "u_fit": float(self.predicted[k, 0]),
                    "v_fit": float(self.predicted[k, 1]),
                    "residual_px": float(self.residuals_px[k]),
                    "radial_residual_px": float(self.radial_residuals_px[k]),
                }
            )
        low, high = self.landmark_range
        return {
            "model": self.model.radial.kind,
            "axis": self.model.radial.axis,
            "axis_source": self.axis_source,
            "azimuth_mode": self.azimuth_mode,
            "s": self.model.s,
            "phi0_deg": math.degrees(self.model.phi0),
            "azimuth_consistency": self.azimuth_consistency,
            "rms_px": self.rms_px,
            "max_px": self.max_px,
            "landmark_elevation_range_deg": [math.degrees(low), math.degrees(high)],
            "model_selection_loo_rms_px": {k: (v if math.isfinite(v) else None) for k, v in self.selection.items()},
            "landmarks": rows,
        }


def fit_camera(
    landmarks: Landmarks,
    camera_position: tuple[float, float, float],
    centre: tuple[float, float],
    *,
    model: str = "auto",
    azimuth: str = "fit",
    axis: str | None = None,
    image_size: tuple[int, int] | None = None,
) -> CameraFit:
    """Fit the camera model to landmark pairs (Algorithm 1 and beyond).

    Parameters
    ----------
    landmarks : Landmarks
        At least 5 pairs, spread in elevation.
    camera_position : (X0, Y0, Z0)
        Mirror (lens) centre O_m in world units.
    centre : (u0, v0)
        Image centre, px.
    model : str
        ``"auto"`` (leave-one-out choice) or one of ``panomap.radial.MODELS``.
    azimuth : {"fit", "paper"}
        Estimate ``s`` and ``phi0``, or take the paper's ``s = +1, phi0 = 0``.
    axis : {"down", "up"}, optional
        Force the viewing direction; found from the landmarks when omitted.
    image_size : (width, height), optional
        When given, landmarks outside the image are refused.

    Raises
    ------
    PanomapError
        Too few landmarks, a landmark at the camera or outside the image, all
        landmarks at one elevation, or no model that fits monotonically.
    """
    if model != "auto" and model not in MODELS:
        raise PanomapError(f"unknown model {model!r}; choose auto or one of {', '.join(MODELS)}")
    if azimuth not in AZIMUTH_MODES:
        raise PanomapError(f"azimuth must be 'fit' or 'paper', not {azimuth!r}")
    if axis is not None and axis not in AXES:
        raise PanomapError(f"axis must be 'down' or 'up', not {axis!r}")
    camera = tuple(float(c) for c in camera_position)
    if len(camera) != 3 or not all(math.isfinite(c) for c in camera):
        raise PanomapError("the camera position must be three finite numbers X0 Y0 Z0")
    u0, v0 = (float(c) for c in centre)
    if not (math.isfinite(u0) and math.isfinite(v0)):
        raise PanomapError("the image centre must be two finite numbers U0 V0")
    n = len(landmarks)
    if n < MIN_LANDMARKS:
        raise PanomapError(f"only {n} landmark(s); at least {MIN_LANDMARKS} are needed")
    if image_size is not None:
        _check_inside(landmarks, image_size)

    d = landmarks.world - np.asarray(camera)
    at_camera = np.flatnonzero(np.linalg.norm(d, axis=1) < 1e-9)
    if at_camera.size:
        raise PanomapError(f"landmark {landmarks.names[at_camera[0]]!r} is at the camera position")
    theta, rho = azimuth_elevation(d)
    if float(np.ptp(rho)) < MIN_ELEVATION_SPREAD:
        raise PanomapError(
            f"all landmarks are at one elevation ({math.degrees(float(np.mean(rho))):.2f} deg, "
            f"spread {math.degrees(float(np.ptp(rho))):.3f} deg); the radial fit needs them spread "
            "in elevation"
        )
    du = landmarks.pixels[:, 0] - u0
    dv = landmarks.pixels[:, 1] - v0
    r = np.hypot(du, dv)
    phi = np.arctan2(dv, du)

    axis_source = "given"
    if axis is None:
        axis, axis_source = _detect_axis(rho, r), "detected"

    selection: dict[str, float] = {}
    low, high = float(rho.min()), float(rho.max())
    if model == "auto":
        radial = None
        best = math.inf
        for kind in AUTO_CANDIDATES:
            try:
                candidate = fit_radial(kind, rho, r, axis)
            except PanomapError:
                selection[kind] = math.inf
                continue
            score = leave_one_out_rms(kind, rho, r, axis) if is_monotonic(candidate, low, high) else math.inf
            selection[kind] = score
            if score < best * (1 - 1e-9) - 1e-9:
                radial, best = candidate, score
        if radial is None:
            raise PanomapError(
                "no radial model fits these landmarks monotonically; check the landmarks, "
                "the camera position and the centre"
            )
    else:
        radial = fit_radial(model, rho, r, axis)
        if not is_monotonic(radial, low, high):
            raise PanomapError(
                f"the {model} fit is not monotonic over the landmarks' elevations "
                f"{math.degrees(low):.1f}..{math.degrees(high):.1f} deg; check the landmarks"
            )

    if azimuth == "paper":
        s, phi0, consistency = 1, 0.0, _consistency(phi - theta, r)
    else:
        s, phi0, consistency = _fit_azimuth(theta, phi, r, np.hypot(d[:, 0], d[:, 1]))
    camera_model = CameraModel((u0, v0), radial, s, phi0)
    predicted = camera_model.pixels(theta, rho)
    residuals = np.linalg.norm(predicted - landmarks.pixels, axis=1)
    return CameraFit(
        model=camera_model,
        landmarks=landmarks,
        camera_position=(camera[0], camera[1], camera[2]),
        theta=theta,
        rho=rho,
        predicted=predicted,
        residuals_px=residuals,
        radial_residuals_px=radial(rho) - r,
        axis_source=axis_source,
        azimuth_mode=azimuth,
        azimuth_consistency=consistency,
        selection=selection,
    )


def _check_inside(landmarks: Landmarks, image_size: tuple[int, int]) -> None:
    width, height = image_size
    u, v = landmarks.pixels[:, 0], landmarks.pixels[:, 1]
    outside = np.flatnonzero((u < -0.5) | (u > width - 0.5) | (v < -0.5) | (v > height - 0.5))
    if outside.size:
        k = outside[0]
        raise PanomapError(
            f"landmark {landmarks.names[k]!r} at pixel ({u[k]:g}, {v[k]:g}) is outside the {width} x {height} image"
        )


def _detect_axis(rho: FloatArray, r: FloatArray) -> str:
    """``"down"`` when the image radius grows with elevation, else ``"up"``."""
    correlation = stats.spearmanr(rho, r).statistic
    if not np.isfinite(correlation) or abs(correlation) < 0.5:
        raise PanomapError(
            "cannot tell from the landmarks whether the camera looks down or up (image radius "
            f"and elevation are not monotonically related, Spearman {correlation:.2f}); "
            "check the centre and camera position, or force the axis"
        )
    return "down" if correlation > 0 else "up"


def _consistency(delta: FloatArray, weights: FloatArray) -> float:
    w = weights**2
    total = float(w.sum())
    if total <= 0:
        return 0.0
    return float(np.hypot(w @ np.cos(delta), w @ np.sin(delta)) / total)


def _fit_azimuth(theta: FloatArray, phi: FloatArray, r: FloatArray, horizontal: FloatArray) -> tuple[int, float, float]:
    """Handedness s and offset phi0 (rad) by a circular mean weighted by r^2.

    Landmarks on the optical axis (no azimuth) or at the image centre (no
    image angle) carry no weight.
    """
    weights = np.where((horizontal > 1e-12) & (r > 1e-9), r, 0.0)
    if not np.any(weights > 0):
        raise PanomapError("no landmark away from the image centre and the optical axis to fix the azimuth")
    best: tuple[int, float, float] | None = None
    for s in (1, -1):
        delta = phi - s * theta
        w = weights**2
        phi0 = float(np.arctan2(w @ np.sin(delta), w @ np.cos(delta)))
        consistency = _consistency(delta, weights)
        if best is None or consistency > best[2]:
            best = (s, phi0, consistency)
    assert best is not None
    return best
