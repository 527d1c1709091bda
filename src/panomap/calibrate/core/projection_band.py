"""The projection uncertainty of a camera learned from checkerboards, as the table's report stores it.

Convention: rings are angles alpha (deg) of a ray from the pole the image centre sees (the camera's axes of
:mod:`..lines.rays`); azimuths phi (deg) are the image angle; bands are pixel distances (px) at 95%.

What it says: where, across the image, the table's pixel of a ray would lie had the corners been found with
other noise of the same size (:mod:`..boards.uncertainty` makes it). The band covers the corners' noise carried
through the fit (and, for a law chosen from the corners, a stretch of the camera along its axis); not a camera
that is not rotationally symmetric, nor corners found off by the same amount.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ...errors import PanomapError, refusal
from ...geometry import FloatArray

#: The table is refused where a ring inside the boards' field has a 95% band over this (px): the lines' fit's
#: ceiling (:data:`..lines.agreement.MAX_BAND_PX`).
MAX_BAND_PX = 2.0
#: A ring this close (deg) to an end of the boards' field counts as that end, for the advice.
END_DEG = 5.0


@dataclass(frozen=True)
class ProjectionBand:
    """The 95% band of the table's pixels, ring by ring and azimuth by azimuth.

    Attributes
    ----------
    alpha_deg : (m,) tuple of float
        The rings' angles from the axis, deg.
    azimuth_deg : (k,) tuple of float
        The azimuths sampled on each ring, deg.
    pixel_band_px : (m, k) tuple of tuples of float
        The 95th percentile of the distance (px) a pixel there moves with the corners' noise.
    ring_band_px : (m,) tuple of float
        The 95th percentile of the largest such distance along each ring (px): the ring's band.
    field_deg : (low, high)
        The angles from the axis (deg) between which 90% of the boards' corners lie (their 5th and 95th
        percentiles): where the band is judged.
    sigma_px : float
        The corners' noise per coordinate (px): the fit's residuals over its degrees of freedom.
    corners, boards, parameters : int
        What the fit saw: the corners, the boards, and the parameters fitted (camera and poses).
    correlation : float
        The residuals' correlation between neighbouring corners of a board (0-0.9): the noise's variance was
        carried through the fit ``(1 + c) / (1 - c)`` times, as correlated residuals hold fewer independent
        measurements.
    stretch : bool
        Whether the camera was left free to stretch along its axis (a law chosen from the corners, not given).
    """

    alpha_deg: tuple[float, ...]
    azimuth_deg: tuple[float, ...]
    pixel_band_px: tuple[tuple[float, ...], ...]
    ring_band_px: tuple[float, ...]
    field_deg: tuple[float, float]
    sigma_px: float
    corners: int
    boards: int
    parameters: int
    correlation: float = 0.0
    stretch: bool = False

    def inside(self) -> FloatArray:
        """Mask (m,) of the rings inside the boards' field (a ring within half a step of it counts)."""
        alpha = np.asarray(self.alpha_deg)
        step = float(np.median(np.diff(alpha))) if alpha.size > 1 else 0.0
        low, high = self.field_deg
        mask = (alpha >= low - step / 2) & (alpha <= high + step / 2)
        if not mask.any() and alpha.size:  # a field narrower than a ring's step: its nearest ring
            mask[int(np.argmin(np.abs(alpha - (low + high) / 2)))] = True
        return np.asarray(mask)

    def worst_inside(self) -> tuple[float, float]:
        """The widest ring band inside the boards' field (px) and its ring (deg); (0, nan) without rings."""
        band = np.asarray(self.ring_band_px)[self.inside()]
        if not band.size:
            return 0.0, float("nan")
        worst = int(np.argmax(band))
        return float(band[worst]), float(np.asarray(self.alpha_deg)[self.inside()][worst])

    def refusal(self, pictures: int) -> str | None:
        """One sentence saying what pictures to add where a ring inside the boards' field has a band over
        ``MAX_BAND_PX``; None where none has. ``pictures``: how many the boards came from."""
        worst_px, at_deg = self.worst_inside()
        if worst_px <= MAX_BAND_PX:
            return None
        low, high = self.field_deg
        if self.boards == 1:
            advice = "add pictures with the board elsewhere, tilted 30-60 deg, near and far"
        elif at_deg >= high - END_DEG:
            advice = "add pictures with a board nearer the image circle's rim, tilted"
        elif at_deg <= low + END_DEG:
            advice = "add pictures with a board nearer the image centre, tilted"
        else:
            advice = "add pictures with the boards tilted 30-60 deg, near and far"
        who = "the checkerboard does" if self.boards == 1 else f"the {self.boards} checkerboards do"
        shown = f"{worst_px:.1f}" if round(worst_px, 1) > MAX_BAND_PX else f"{worst_px:.2f}"  # (not "2.0 px" over 2)
        summary = f"{who} not pin the camera ({shown} px at 95% at {at_deg:.0f} deg off the axis): {advice}"
        figures = (
            f"the corners' noise ({self.sigma_px:.2f} px per coordinate, from {self.corners} corners in {pictures} "
            f"picture(s), {self.parameters} parameters fitted{self._how()}) carried through the fit moves the "
            f"table's pixels by up to {worst_px:.1f} px (95%) at {at_deg:.0f} deg from the axis, inside the boards' "
            f"field ({low:.0f}-{high:.0f} deg, 90% of the corners); a table needs its 95% band within "
            f"{MAX_BAND_PX:.0f} px there"
        )
        return refusal(summary, figures)

    def _how(self) -> str:
        """What the noise was carried with: its correlation's factor, the stretch."""
        factor = (1.0 + self.correlation) / (1.0 - self.correlation)
        return (
            f"; its variance x{factor:.1f} for the residuals' correlation {self.correlation:.2f}"
            if factor > 1.005
            else ""
        ) + ("; the stretch along the axis free" if self.stretch else "")

    def sentences(self) -> list[str]:
        """The band in two lines, for the terminal: the figures, then what they come from."""
        worst_px, at_deg = self.worst_inside()
        band = np.asarray(self.ring_band_px)
        inside = band[self.inside()]
        rim = int(np.argmax(band)) if band.size else 0
        median = float(np.median(inside)) if inside.size else float("nan")
        beyond = (
            f"; {band[rim]:.2f} px at {self.alpha_deg[rim]:.0f} deg"
            if band.size and band[rim] > worst_px + 0.005
            else ""
        )
        return [
            f"projection uncertainty (95%): within the boards' field ({self.field_deg[0]:.0f}-{self.field_deg[1]:.0f}"
            f" deg off the axis) median {median:.2f} px, worst ring {worst_px:.2f} px at {at_deg:.0f} deg{beyond}",
            f"  from the corners' {self.sigma_px:.2f} px of noise{self._how()}, through the fit",
        ]

    def to_dict(self) -> dict[str, Any]:
        return {
            "alpha_deg": list(self.alpha_deg),
            "azimuth_deg": list(self.azimuth_deg),
            "pixel_band_px": [[round(x, 4) for x in row] for row in self.pixel_band_px],
            "ring_band_px": list(self.ring_band_px),
            "field_deg": list(self.field_deg),
            "sigma_px": self.sigma_px,
            "corners": self.corners,
            "boards": self.boards,
            "parameters": self.parameters,
            "correlation": self.correlation,
            "stretch": self.stretch,
        }

    @classmethod
    def from_dict(cls, data: Any) -> ProjectionBand:
        try:
            low, high = data["field_deg"]
            band = cls(
                alpha_deg=tuple(float(a) for a in data["alpha_deg"]),
                azimuth_deg=tuple(float(a) for a in data["azimuth_deg"]),
                pixel_band_px=tuple(tuple(float(x) for x in row) for row in data["pixel_band_px"]),
                ring_band_px=tuple(float(x) for x in data["ring_band_px"]),
                field_deg=(float(low), float(high)),
                sigma_px=float(data["sigma_px"]),
                corners=int(data["corners"]),
                boards=int(data["boards"]),
                parameters=int(data["parameters"]),
                correlation=float(data.get("correlation", 0.0)),
                stretch=bool(data.get("stretch", False)),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise PanomapError(f"the projection uncertainty of the fit report is malformed ({exc})") from None
        m, k = len(band.alpha_deg), len(band.azimuth_deg)
        if len(band.ring_band_px) != m or len(band.pixel_band_px) != m or any(len(r) != k for r in band.pixel_band_px):
            raise PanomapError(
                f"the projection uncertainty of the fit report is malformed ({m} rings, {k} azimuths, bands of "
                "other shapes)"
            )
        return band
