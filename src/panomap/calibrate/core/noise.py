"""The noise model: the landmarks as observations, and their residuals whitened by it (beyond the paper).

Convention: world Z up; a landmark's ray is ``d = P - O_m`` in the camera's axes; azimuth theta and
elevation rho as in :mod:`panomap.geometry`; pixel radius r and image angle phi about the image centre;
the model puts a landmark at ``r = f_r(rho)``, ``phi = s*theta + phi0``.

Each landmark's residual is split into a radial and a tangential part (px), each with its own standard
deviation: the pixel's (``pixel_sigma``, default 1 px) combined with the world point's (``world_sigma``,
default 0.4% of the median landmark distance, about a centimetre in a room) seen through the camera:
``f_r'(rho) sigma_w / |d|`` radially and ``r sigma_w / |d_xy|`` tangentially. Every fit minimises these
whitened residuals (the effective-variance method), and every score is made of them:
:func:`landmark_residuals` is the one place they are computed.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...camera.radial import RadialFunction
from ...camera.radial_models import RadialKind
from ...camera.uncertainty import coefficient_covariance, radius_standard_error
from ...errors import PanomapError
from ...geometry import FloatArray

DEFAULT_WORLD_SIGMA_FRACTION = 0.004
# A landmark this many pixel sigmas beyond the cut-off disc or the image circle is measurement noise: kept.
RIM_SLACK_SIGMAS = 3.0


@dataclass(frozen=True)
class Observations:
    """Per-landmark quantities the fits share, in one frame of the camera; arrays of shape (n,).

    Attributes
    ----------
    theta, rho : (n,) ndarray
        The landmarks' azimuth and elevation (rad) in the camera's axes.
    r, phi : (n,) ndarray
        Their pixels' radius (px) and image angle (rad) about the centre.
    sigma_rho, sigma_theta : (n,) ndarray
        The world point's error seen as an elevation and an azimuth error (rad).
    pixel_sigma : float
        px.
    axis : {"down", "up"}
    s : {+1, -1}
    azimuth_mode : {"fit", "paper"}
    """

    theta: FloatArray
    rho: FloatArray
    r: FloatArray
    phi: FloatArray
    sigma_rho: FloatArray  # rad: the world point's error seen as an elevation error
    sigma_theta: FloatArray  # rad: ... as an azimuth error
    pixel_sigma: float
    axis: str
    s: int
    azimuth_mode: str
    # The fits made on these data: (model, the subset's bytes) -> (f_r, phi0), or the error it raised. A fit
    # is a pure function of the data and the subset, and the choice asks for many twice (the outlier search
    # and the model choice refit the same subsets: 35% of them on 40 landmarks). Not copied by replace().
    fitted: dict[tuple[RadialKind, bytes], tuple[RadialFunction, float] | PanomapError] = field(
        default_factory=dict, init=False, repr=False, compare=False
    )


@dataclass(frozen=True)
class Residuals:
    """Landmarks' residuals (px) and their standard deviations (px), each (m,).

    ``radial_px`` is ``f_r(rho) - r``; ``tangential_px`` is ``r`` times the wrapped angle
    ``s*theta + phi0 - phi``.
    """

    radial_px: FloatArray
    tangential_px: FloatArray
    radial_sigma_px: FloatArray
    tangential_sigma_px: FloatArray

    @property
    def whitened(self) -> tuple[FloatArray, FloatArray]:
        """The radial and tangential residuals in standard deviations, each (m,)."""
        return self.radial_px / self.radial_sigma_px, self.tangential_px / self.tangential_sigma_px

    @property
    def whitened_norm(self) -> FloatArray:
        """sqrt(z_radial^2 + z_tangential^2) of each landmark (m,)."""
        radial, tangential = self.whitened
        return np.asarray(np.hypot(radial, tangential))

    @property
    def pixel_norm(self) -> FloatArray:
        """Distance (px) between each landmark and where the model puts it (m,)."""
        return np.asarray(np.hypot(self.radial_px, self.tangential_px))


def landmark_residuals(
    radial: RadialFunction,
    phi0: float,
    s: int,
    theta: FloatArray,
    rho: FloatArray,
    r: FloatArray,
    phi: FloatArray,
    radial_sigma: FloatArray,
    sigma_theta: FloatArray,
    pixel_sigma: float,
) -> Residuals:
    """The noise model's residuals of landmarks (m,) at ``theta, rho`` (rad) seen at ``r`` (px), ``phi`` (rad).

    ``radial_sigma`` (px) is given (:func:`radial_sigma`, held fixed while a fit runs: the effective-variance
    method); the tangential sigma is ``sqrt(pixel_sigma^2 + (r sigma_theta)^2)`` (px).
    """
    angle = np.angle(np.exp(1j * (s * theta + phi0 - phi)))
    tangential_sigma = np.sqrt(pixel_sigma**2 + (r * sigma_theta) ** 2)
    return Residuals(radial(rho) - r, r * angle, radial_sigma, tangential_sigma)


def radial_sigma(
    radial: RadialFunction | None, rho: FloatArray, sigma_rho: FloatArray, pixel_sigma: float
) -> FloatArray:
    """Standard deviation (px) of each landmark's radial residual: ``sqrt(pixel_sigma^2 + (f_r' sigma_rho)^2)``."""
    slope = np.zeros_like(rho) if radial is None else np.nan_to_num(radial.slope(rho))
    return np.sqrt(pixel_sigma**2 + (slope * sigma_rho) ** 2)


def world_sigmas(d: FloatArray, world_sigma: float) -> tuple[FloatArray, FloatArray]:
    """The world point's error (``world_sigma``, world units) seen as an elevation and an azimuth error (rad),
    for rays ``d`` (n, 3) in the camera's axes."""
    distance = np.linalg.norm(d, axis=1)
    horizontal = np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-12)
    return world_sigma / distance, world_sigma / horizontal


def observation_residuals(
    radial: RadialFunction, phi0: float, data: Observations, index: Any, prediction_se: FloatArray | None = None
) -> Residuals:
    """:func:`landmark_residuals` of the observations at ``index``; the radial standard deviation includes
    ``prediction_se`` (px, one per landmark) where given."""
    sigma = radial_sigma(radial, data.rho, data.sigma_rho, data.pixel_sigma)[index]
    if prediction_se is not None:
        sigma = np.sqrt(sigma**2 + prediction_se**2)
    return landmark_residuals(
        radial,
        phi0,
        data.s,
        data.theta[index],
        data.rho[index],
        data.r[index],
        data.phi[index],
        sigma,
        data.sigma_theta[index],
        data.pixel_sigma,
    )


def radial_weights(radial: RadialFunction | None, data: Observations) -> FloatArray:
    """1 / each landmark's radial standard deviation (1/px): the weights of a radial least squares."""
    return 1.0 / radial_sigma(radial, data.rho, data.sigma_rho, data.pixel_sigma)


def tangential_sigma(data: Observations, r: FloatArray) -> FloatArray:
    """Standard deviation (px) of each landmark's tangential residual at radius ``r`` (px)."""
    return np.sqrt(data.pixel_sigma**2 + (r * data.sigma_theta) ** 2)


def prediction_se(radial: RadialFunction, data: Observations, fitted: FloatArray, index: Any) -> FloatArray:
    """Standard error (px) of f_r at the landmarks at ``index``, f_r fitted to those in ``fitted`` (bool mask)
    under the noise model (the weights are 1 / the residuals' standard deviations)."""
    if not radial.spec.weighted:
        return np.zeros(np.size(data.rho[index]))
    weights = radial_weights(radial, data)[fitted]
    covariance = coefficient_covariance(radial, data.rho[fitted], data.r[fitted], weights, noise_known=True)
    return np.nan_to_num(radius_standard_error(radial, covariance, data.rho[index]), nan=0.0)


def rim_slack_px(pixel_sigma: float) -> float:
    """How far (px) a landmark may lie beyond the annulus and still count as on it: measurement noise."""
    return RIM_SLACK_SIGMAS * pixel_sigma
