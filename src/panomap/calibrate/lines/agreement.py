"""Whether a picture pins its camera: how far apart the cameras lie that explain its lines equally well.

Convention: as in :mod:`.rays` (alpha, rad, the angle of a ray from the pole the image centre sees; pixels
(u, v) px); a camera here is a radial kind and its parameters ``[u0, v0, *coefficients]``.

Straightness leaves the scale of the elevations nearly free (a linear map of the rays keeps every line
straight; :mod:`.families`), and on real pictures the fit can settle, every line straight, at a camera tens
of px from the truth while the Jacobian of a stiff law claims a fraction of a px. What the picture itself
can say is how far apart the cameras lie that it cannot tell apart:

- **alternatives**: the ends of the other starts, and the other radial kinds, that the picture does not rule
  out (:func:`ruled_out`): a kind whose held-out lines, line by line, are not significantly less straight than
  the chosen kind's; a start whose end leaves the chosen lines and their right angles, unit by unit, not
  significantly less explained. Units, not points: a line's points err alike along it;
- **folds**: the chosen kind refitted without each fold of lines (the cross-validation's own fits): a
  grouped jackknife, whose spread counts a line's points as the one measurement they are (a line's
  points err alike along it; the Jacobian takes them as independent);
- **the stretch**: the chosen camera stretched along its axis (:mod:`.stretch`) by the least and the largest
  ``s`` its right angles do not reject (:func:`.stretch.stretch_range`). Every line is exactly as straight under
  each, so no other start or kind need land there for the picture to be unable to tell them apart. Without it, a
  picture whose lines run along and across the axis was accepted wherever the other starts and kinds happened to
  agree: a level room through a mirror whose law is the unified one stretched 6%, 4.5 px off (issue 55, where a
  held-out mirror camera's picture was accepted 13 px off).

Each is compared with the chosen camera as the outside checks compare a camera with its calibration
(:func:`displacement_px`): pixels on rings about the chosen camera's centre, each pixel's ray under both,
the other's rays turned by the one best orthogonal matrix, projected by the chosen camera; the largest
distance on each ring. The 95% band of the radius at each ring is then
``1.96 sqrt(se_jacobian^2 + se_jackknife^2) + (largest alternative's distance)``: the alternatives are
not noise about the answer but answers the picture cannot rule out.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ...camera.radial import RadialFunction
from ...errors import PanomapError, refusal
from ...geometry import FloatArray
from .rays import InverseRadial
from .stretch import OBLIQUE_MIN_DEG, StretchRange, obliqueness_deg

# Another camera is ruled out when it leaves the lines (and right angles), unit by unit, less explained than the
# chosen one at this one-sided significance.
RULED_OUT_P = 0.025
# Two-sided 95% of a normal error.
Z95 = 1.96
# The table is refused where the 95% band exceeds this anywhere on the rings (px) ...
MAX_BAND_PX = 2.0
# ... or at this share of the rings, this many px (the goal of a table: p90 1 px, max 2 px).
P90_BAND_PX = 1.0
BAND_QUANTILE = 90.0
# The rings: from this angle off the axis (near the axis a px of error is a large angle nobody uses; the outside
# checks start at 15 deg) to the image circle's rim (or the farthest line); the refusal judges them up to this
# angle (the outside checks' last ring), the reported band covers them all.
RING_FROM_DEG = 15.0
RING_TO_DEG = 85.0
RING_STEP_DEG = 2.5
# Azimuths per ring.
RING_AZIMUTHS = 72


@dataclass(frozen=True)
class Camera:
    """One camera the lines allow: a radial kind and ``params`` = [u0, v0, *coefficients]; ``source`` says which."""

    kind: str
    params: FloatArray
    source: str


@dataclass(frozen=True)
class PinnedBand:
    """How well the picture pins the chosen camera, ring by ring.

    Attributes
    ----------
    alpha_deg : (m,) float64
        The rings' angles from the axis, deg.
    jackknife_se_px : (m,) float64
        The grouped jackknife's standard error of the pixel there (px).
    alternative_px : (m,) float64
        The farthest alternative's distance there (px).
    farthest : str
        Which alternative that is, at the ring where the band is widest.
    oblique_deg : float
        The most oblique family of lines at right angles to another (:func:`.stretch.obliqueness_deg`, deg); NaN
        without such families.
    """

    alpha_deg: FloatArray
    jackknife_se_px: FloatArray
    alternative_px: FloatArray
    farthest: str
    oblique_deg: float = math.nan

    def se_px(self, jacobian_se_px: FloatArray) -> FloatArray:
        """The honest standard error (px) at the rings, with the Jacobian's ``jacobian_se_px`` (m,): the 95% band
        over ``Z95``."""
        return np.asarray(
            np.sqrt(jacobian_se_px**2 + self.jackknife_se_px**2) + self.alternative_px / Z95, dtype=np.float64
        )

    def refusal(self, jacobian_se_px: FloatArray, lines: int, pictures: int = 1) -> str | None:
        """One sentence saying what is missing where the band is too wide for a table; None where it is not."""
        judged = self.alpha_deg <= RING_TO_DEG + 1e-9
        band = Z95 * self.se_px(jacobian_se_px)[judged]
        if not band.size:
            return None
        worst = int(np.argmax(band))
        with np.errstate(invalid="ignore"):  # a ring an alternative does not reach is inf: so is the percentile
            p90 = float(np.percentile(band, BAND_QUANTILE))
        if band[worst] <= MAX_BAND_PX and p90 <= P90_BAND_PX:
            return None
        at_deg = float(self.alpha_deg[judged][worst])
        spread = (
            f"differ by up to {band[worst]:.1f} px at {at_deg:.0f} deg from the axis"
            if np.isfinite(band[worst])
            else f"disagree at {at_deg:.0f} deg from the axis, where one of them sees no ray at all"
        )
        its = "its" if pictures == 1 else "their"
        who = "the picture does" if pictures == 1 else f"the {pictures} pictures do"
        figures = (
            f"cameras that explain {its} {lines} straight lines about equally well ({self.farthest}, the lines in "
            f"folds) {spread} (a table needs its 95% band within {P90_BAND_PX:.0f} px at {BAND_QUANTILE:.0f}% of the "
            f"rings and {MAX_BAND_PX:.0f} px at all)"
        )
        if self.oblique_deg < OBLIQUE_MIN_DEG:
            return refusal(
                f"{who} not pin the camera, {its} lines all along or across its axis: give a checkerboard held tilted",
                f"{figures}; {its} lines run along and across the camera's axis (every direction within "
                f"{self.oblique_deg:.1f} deg), where a camera stretched along its axis keeps them straight and their "
                "right angles square, so more such pictures cannot pin it: a checkerboard held tilted, in a few "
                "pictures, near and far, can",
            )
        return refusal(
            f"{who} not pin the camera: give more pictures with long straight edges, or a checkerboard",
            f"{figures}; long straight edges of the room's three directions (walls' corners, floor and ceiling "
            "edges, door and window frames) across the whole image circle pin it",
        )


def ruled_out(theirs: FloatArray, mine: FloatArray) -> bool:
    """Whether the units (lines, pairs) leave ``theirs`` (n,) significantly more unexplained than ``mine`` (n,)
    (px^2 each): Wilcoxon's signed-rank test of the paired differences, one-sided, at ``RULED_OUT_P``. Ranks, not
    sizes: one pair of families that is not quite square (or one line that is not quite straight) must not
    decide. Units, not points: a line's points err alike along it."""
    from scipy.stats import wilcoxon  # here, not at the top: importing SciPy is slow

    if not np.isfinite(theirs).all():
        return True
    difference = theirs - mine
    difference = difference[np.abs(difference) > 1e-12 * max(float(np.max(np.abs(mine))), 1e-12)]
    if difference.size < 6:
        return bool(difference.size and np.all(difference > 0))
    return bool(wilcoxon(difference, alternative="greater").pvalue < RULED_OUT_P)


def ring_alphas(reach_alpha: float) -> FloatArray:
    """The rings' angles (rad) from ``RING_FROM_DEG`` to ``reach_alpha`` (the refusal judges those up to
    ``RING_TO_DEG``; the reported band covers them all)."""
    top = math.degrees(reach_alpha)
    return np.radians(np.arange(RING_FROM_DEG, max(top, RING_FROM_DEG) + 1e-9, RING_STEP_DEG))


def _radial(camera: Camera, axis: str) -> RadialFunction:
    return RadialFunction(camera.kind, tuple(float(c) for c in camera.params[2:]), axis)


def _radius_of_alpha(radial: RadialFunction, alpha: FloatArray) -> FloatArray:
    rho = alpha - math.pi / 2 if radial.axis == "down" else math.pi / 2 - alpha
    return np.abs(np.asarray(radial(rho), dtype=np.float64))


def displacement_px(chosen: Camera, other: Camera, axis: str, alpha: FloatArray) -> FloatArray:
    """The largest distance (px) on each ring ``alpha`` (m,) rad between the chosen camera's pixels and where it
    puts the other camera's rays of them, after the best orthogonal map of the rays (inf where the other camera
    does not reach a ring)."""
    chosen_radial, other_radial = _radial(chosen, axis), _radial(other, axis)
    radius = _radius_of_alpha(chosen_radial, alpha)
    phi = np.linspace(0.0, 2.0 * math.pi, RING_AZIMUTHS, endpoint=False)
    centre = chosen.params[:2]
    pixels = centre + (radius[:, None, None] * np.stack([np.cos(phi), np.sin(phi)], axis=1)[None]).reshape(-1, 2)
    pixels = pixels.reshape(-1, 2)
    mine = _rays(chosen.params[:2], np.repeat(alpha, phi.size), pixels)
    try:
        reach = float(np.max(np.hypot(*(pixels - other.params[:2]).T))) * 1.01 + 1.0
        inverse = InverseRadial.of(other_radial, reach)
    except PanomapError:
        return np.full(alpha.shape, math.inf)
    r_other = np.hypot(*(pixels - other.params[:2]).T)
    alpha_other, _ = inverse(r_other)
    theirs = _rays(other.params[:2], alpha_other, pixels)
    if not np.isfinite(theirs).all():
        return np.full(alpha.shape, math.inf)
    u, _, vt = np.linalg.svd(mine.T @ theirs)
    turned = theirs @ (u @ vt).T
    back_alpha = np.arccos(np.clip(turned[:, 2], -1.0, 1.0))
    back_phi = np.arctan2(turned[:, 1], turned[:, 0])
    back_r = _radius_of_alpha(chosen_radial, back_alpha)
    back = centre + back_r[:, None] * np.stack([np.cos(back_phi), np.sin(back_phi)], axis=1)
    distance = np.hypot(*(back - pixels).T).reshape(alpha.size, phi.size)
    return np.asarray(np.where(np.isfinite(distance), distance, math.inf).max(axis=1), dtype=np.float64)


def stretch_displacement_px(chosen: Camera, s: float, axis: str, alpha: FloatArray) -> FloatArray:
    """The distance (px) on each ring ``alpha`` (m,) rad between the chosen camera's pixels and where it puts the
    rays of the camera stretched by ``s`` along its axis: ``|r(alpha') - r(alpha)|``, ``tan(alpha') = tan(alpha) /
    s`` (the rings are symmetric about the axis, so the best orthogonal map is the identity); inf where the chosen
    law does not reach ``alpha'``."""
    radial = _radial(chosen, axis)
    stretched = np.arctan2(np.sin(alpha), s * np.cos(alpha))
    with np.errstate(invalid="ignore", over="ignore"):
        distance = np.abs(_radius_of_alpha(radial, stretched) - _radius_of_alpha(radial, alpha))
    return np.asarray(np.where(np.isfinite(distance), distance, math.inf), dtype=np.float64)


def _rays(centre: FloatArray, alpha: FloatArray, pixels: FloatArray) -> FloatArray:
    phi = np.arctan2(pixels[:, 1] - centre[1], pixels[:, 0] - centre[0])
    return np.stack([np.sin(alpha) * np.cos(phi), np.sin(alpha) * np.sin(phi), np.cos(alpha)], axis=1)


def pinned_band(
    chosen: Camera,
    alternatives: Sequence[Camera],
    folds: Sequence[FloatArray],
    axis: str,
    alpha: FloatArray,
    directions: FloatArray | None = None,
    stretch: StretchRange | None = None,
) -> PinnedBand:
    """The band's parts at rings ``alpha`` (rad): the folds' grouped jackknife (``folds``: the chosen kind's
    parameters fitted without each fold) and the farthest of ``alternatives`` and of the chosen camera stretched
    along its axis to either end of ``stretch``; with the ``directions`` (k, 3) of the families at right angles to
    another, under the chosen camera, how oblique the most oblique is."""
    if folds:
        d = np.array([displacement_px(chosen, Camera(chosen.kind, f, "fold"), axis, alpha) for f in folds])
        k = len(folds)
        jackknife = np.sqrt((k - 1) / k * np.sum(d**2, axis=0))
    else:
        jackknife = np.zeros(alpha.shape)
    far = np.zeros(alpha.shape)
    farthest = "no other start or kind came close"
    rows = [displacement_px(chosen, other, axis, alpha) for other in alternatives]
    names = [other.source for other in alternatives]
    for s in () if stretch is None else sorted({stretch.low, stretch.high} - {1.0}):
        rows.append(stretch_displacement_px(chosen, s, axis, alpha))
        names.append(f"the camera stretched along its axis by s = {s:.3f}")
    if rows:
        distances = np.array(rows)
        far = distances.max(axis=0)
        farthest = names[int(np.argmax(distances.max(axis=1)))]
    oblique = float(obliqueness_deg(directions).max()) if directions is not None and len(directions) else math.nan
    return PinnedBand(np.degrees(alpha), jackknife, far, farthest, oblique)
