"""Radial stretching functions r = f_r(rho): a registered kind with its coefficients, and their fit.

Convention: as in :mod:`panomap.camera.radial_models` (rho the elevation, rad;
r the image radius, px; ``axis`` the pole the image centre sees; alpha the
angle from that pole). The kinds and their parameters are declared there; the
range where a function is valid is in :mod:`.valid_range`, the uncertainty of
a fitted one in :mod:`.uncertainty`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..errors import PanomapError
from ..geometry import FloatArray
from .radial_models import AXES, RadialKind, radial_kind


@dataclass(frozen=True)
class RadialFunction:
    """A fitted radial stretching function ``r = f_r(rho)``.

    Parameters
    ----------
    kind : str
        One of ``MODELS``.
    coefficients : tuple of float
        The model's parameters, in the order its kind declares.
    axis : {"down", "up"}
        Which pole the image centre sees. The function carries it because
        every kind but ``paper`` is a function of alpha, the angle from that
        pole, and is evaluated alone (in the fit, the valid range, the
        uncertainty) before any camera model exists; the table file keeps it
        here. :attr:`panomap.camera.model.CameraModel.axis` is where callers
        read it.
    """

    kind: str
    coefficients: tuple[float, ...]
    axis: str = "down"

    def __post_init__(self) -> None:
        spec = radial_kind(self.kind)
        if self.axis not in AXES:
            raise PanomapError(f"axis must be 'down' or 'up', not {self.axis!r}")
        coefficients = tuple(float(c) for c in self.coefficients)
        if len(coefficients) != spec.parameter_count:
            raise PanomapError(
                f"radial model {self.kind!r} takes {spec.parameter_count} coefficients, got {len(coefficients)}"
            )
        if not all(np.isfinite(coefficients)):
            raise PanomapError(f"radial model {self.kind!r} has non-finite coefficients")
        object.__setattr__(self, "coefficients", coefficients)

    @property
    def spec(self) -> RadialKind:
        """The declared kind: parameters, evaluation, fit."""
        return radial_kind(self.kind)

    def __call__(self, rho: ArrayLike) -> FloatArray:
        """Image radius (px) at elevation(s) ``rho`` (rad); NaN where undefined."""
        return self.spec.evaluate(self.coefficients, np.asarray(rho, dtype=np.float64), self.axis)

    def slope(self, rho: ArrayLike) -> FloatArray:
        """dr/drho (px/rad) at elevation(s) ``rho``, by central differences."""
        rho = np.asarray(rho, dtype=np.float64)
        step = 1e-6
        return (self(rho + step) - self(rho - step)) / (2 * step)

    def to_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "coefficients": list(self.coefficients), "axis": self.axis}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> RadialFunction:
        try:
            return cls(str(data["kind"]), tuple(data["coefficients"]), str(data["axis"]))
        except (KeyError, TypeError, ValueError) as exc:
            if isinstance(exc, PanomapError):
                raise
            raise PanomapError(f"radial model is malformed ({exc})") from None


def fit_radial(kind: str, rho: ArrayLike, r: ArrayLike, axis: str, weights: ArrayLike | None = None) -> RadialFunction:
    """Least-squares fit of one radial model to landmark (rho, r) pairs.

    Parameters
    ----------
    kind : str
        One of ``MODELS``.
    rho : (n,) array_like
        Landmark elevations (rad).
    r : (n,) array_like
        Landmark image radii (px).
    axis : {"down", "up"}
        Which pole the image centre sees; gives the centre pair (the paper's
        (O_c, O_m): ``r = 0`` at ``rho = -pi/2`` looking down, ``+pi/2`` up)
        to the kinds fitted with it (``centre_given``).
    weights : (n,) array_like, optional
        Weight of each landmark's radial residual (1/sigma, 1/px). Kinds that
        are not ``weighted`` ignore them: Algorithm 1 is unweighted.

    Raises
    ------
    PanomapError
        If the data cannot determine the model's parameters.
    """
    spec = radial_kind(kind)
    rho = np.asarray(rho, dtype=np.float64)
    r = np.asarray(r, dtype=np.float64)
    distinct = _distinct_count(rho)
    needed = spec.needed_elevations
    if distinct < needed:
        raise PanomapError(
            f"model {kind!r} needs landmarks at {needed} or more distinct elevations, these are at {distinct}"
        )
    w = None if weights is None or not spec.weighted else np.asarray(weights, dtype=np.float64)
    return RadialFunction(kind, spec.fit(rho, r, axis, w), axis)


def _distinct_count(rho: FloatArray, tolerance: float = 1e-4) -> int:
    """Number of distinct elevations, counting values closer than ``tolerance`` rad as one."""
    values = np.sort(rho[np.isfinite(rho)])
    if values.size == 0:
        return 0
    return int(1 + np.count_nonzero(np.diff(values) > tolerance))
