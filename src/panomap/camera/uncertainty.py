"""The uncertainty of a fitted radial function: its coefficients' covariance and the radius's standard error.

Derivatives are forward differences with a step of 1e-6 of each coefficient
(at least 1e-6 absolute).
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from ..geometry import FloatArray
from .radial_models import with_centre_pair

if TYPE_CHECKING:
    from .radial import RadialFunction


def coefficient_covariance(
    radial: RadialFunction,
    rho: FloatArray,
    r: FloatArray,
    weights: FloatArray | None = None,
    *,
    noise_known: bool = False,
) -> FloatArray:
    """Covariance (p, p) of the coefficients from the weighted residuals' Jacobian.

    ``C = (J^T J)^-1 s^2`` with J the Jacobian of the weighted radial residuals
    and ``s^2`` their sum of squares over the degrees of freedom (1 when there
    are none, or with ``noise_known``: the weights are then 1 / the residuals'
    standard deviations). A kind fitted with the centre pair (``paper``) counts it as a
    residual; one that is not ``weighted`` ignores ``weights``.
    """
    spec = radial.spec
    if not spec.weighted:
        weights = None
    if spec.centre_given:
        rho, r = with_centre_pair(rho, r, radial.axis)
        weights = None if weights is None else np.concatenate([[1.0], weights])
    w = np.ones_like(r) if weights is None else np.asarray(weights, dtype=np.float64)
    differences, steps = _coefficient_differences(radial, rho)
    jacobian = w[:, None] * differences / steps
    residual = w * (radial(rho) - r)
    dof = rho.size - steps.size
    scale = float(residual @ residual / dof) if dof > 0 and not noise_known else 1.0
    normal = jacobian.T @ jacobian
    if not np.all(np.isfinite(normal)) or not math.isfinite(scale):
        return np.full(normal.shape, np.nan)  # f_r undefined at some landmark: no uncertainty to tell
    return np.asarray(np.linalg.pinv(normal) * scale)


def radius_standard_error(radial: RadialFunction, covariance: FloatArray, rho: ArrayLike) -> FloatArray:
    """Standard error (px) of f_r at elevation(s) ``rho`` given the coefficients' covariance."""
    differences, steps = _coefficient_differences(radial, np.asarray(rho, dtype=np.float64))
    gradient = differences / steps
    variance = np.einsum("...i,ij,...j->...", gradient, covariance, gradient)
    return np.sqrt(np.maximum(variance, 0.0))


def _coefficient_differences(radial: RadialFunction, rho: FloatArray) -> tuple[FloatArray, FloatArray]:
    """``f_r`` with coefficient k stepped, less ``f_r``, at ``rho`` (shape (..., p)); the steps (p,)."""
    base = np.asarray(radial.coefficients)
    differences = np.empty((*rho.shape, base.size))
    steps = np.empty(base.size)
    for k in range(base.size):
        steps[k] = 1e-6 * max(1.0, abs(base[k]))
        shifted = base.copy()
        shifted[k] += steps[k]
        differences[..., k] = replace(radial, coefficients=tuple(shifted))(rho) - radial(rho)
    return differences, steps
