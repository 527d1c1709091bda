"""The camera model behind a pano-mapping table: centre, azimuth mapping, f_r.

Convention: ``u = u0 + r cos(phi)``, ``v = v0 + r sin(phi)``,
``phi = s*theta + phi0`` and ``r = f_r(rho)``; theta, rho in rad as in
:mod:`panomap.geometry`. The paper's assumption is ``s = +1, phi0 = 0``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..errors import PanomapError
from ..geometry import FloatArray
from .radial import RadialFunction


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
    """

    centre: tuple[float, float]
    radial: RadialFunction
    s: int = 1
    phi0: float = 0.0

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

    @property
    def axis(self) -> str:
        """Which pole the image centre sees: ``"down"`` (a ceiling camera) or ``"up"``.

        The radial function carries it (it is a function of the angle from
        that pole, and the table file stores it with it); read it here.
        """
        return self.radial.axis

    def image_angle(self, theta: ArrayLike) -> FloatArray:
        """Image angle phi (rad) of azimuth(s) theta (rad)."""
        return self.s * np.asarray(theta, dtype=np.float64) + self.phi0

    def pixels(self, theta: ArrayLike, rho: ArrayLike) -> FloatArray:
        """Pixels (..., 2) of rays with azimuth ``theta`` and elevation ``rho`` (rad)."""
        r = self.radial(rho)
        phi = self.image_angle(theta)
        u0, v0 = self.centre
        return np.stack([u0 + r * np.cos(phi), v0 + r * np.sin(phi)], axis=-1)

    def to_dict(self) -> dict[str, Any]:
        return {
            "centre": list(self.centre),
            "s": self.s,
            "phi0_rad": self.phi0,
            "radial": self.radial.to_dict(),
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> CameraModel:
        try:
            u0, v0 = data["centre"]
            return cls((u0, v0), RadialFunction.from_dict(data["radial"]), int(data["s"]), float(data["phi0_rad"]))
        except (KeyError, TypeError, ValueError) as exc:
            if isinstance(exc, PanomapError):
                raise
            raise PanomapError(f"camera model is malformed ({exc})") from None
