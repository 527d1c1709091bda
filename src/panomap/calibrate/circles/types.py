"""What the circle finder finds: :class:`Circle`, :class:`Ellipse`, :class:`ImageCircles`, the rim in
progress, and :class:`NoImageCircle`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ...errors import PanomapError
from ...geometry import FloatArray
from .thresholds import CONVINCING_RIM_FRACTION


class NoImageCircle(PanomapError):
    """No rim is visible: a full-frame fisheye, a mirror image that overfills the frame, an ordinary photo
    or a blank image.

    Attributes
    ----------
    frame_centre : (u, v)
        The middle of the frame, px: a starting value for a centre that the
        landmarks then refine.
    cutoff : Circle or None
        The cut-off disc, where one shows without a rim (a mirror camera whose
        image overfills the frame): its centre is the better starting value.
    reason : str
        The figures behind the message: what the search found instead (how many rays crossed a rim), or "".
    seen : str
        What the picture showed, without the message's advice on where a centre may start (for a caller
        that takes its centre from elsewhere: an imported calibration's); the message where not given.
    """

    def __init__(
        self,
        message: str,
        frame_centre: tuple[float, float],
        source: object | None = None,
        cutoff: Circle | None = None,
        reason: str = "",
        seen: str = "",
    ) -> None:
        super().__init__(message, source)
        self.frame_centre = frame_centre
        self.cutoff = cutoff
        self.reason = reason
        self.seen = seen or message


class ShortArc(PanomapError):
    """A rim that shows, but on so short an arc that it does not fix its centre: no full-frame fisheye."""


@dataclass(frozen=True)
class Circle:
    """A fitted circle.

    Attributes
    ----------
    centre : (u, v), px
    radius : float, px
    rms_px : float
        RMS distance of the inlier edge points from the circle.
    inliers, rays : int
        Edge points used, out of the rays cast.
    """

    centre: tuple[float, float]
    radius: float
    rms_px: float
    inliers: int
    rays: int

    def to_dict(self) -> dict[str, Any]:
        return {
            "centre": list(self.centre),
            "radius": self.radius,
            "rms_px": self.rms_px,
            "inliers": self.inliers,
            "rays": self.rays,
        }


@dataclass(frozen=True)
class Ellipse:
    """An ellipse fitted to the rim: centre (px), semi-axes (px), angle of the first axis (deg)."""

    centre: tuple[float, float]
    semi_axes: tuple[float, float]
    angle_deg: float

    def to_dict(self) -> dict[str, Any]:
        return {"centre": list(self.centre), "semi_axes": list(self.semi_axes), "angle_deg": self.angle_deg}


@dataclass(frozen=True)
class ImageCircles:
    """What :func:`find_image_circles` found.

    The valid region of the image is the image circle intersected with the frame.

    Attributes
    ----------
    centre : (u0, v0)
        The image centre: the rim's centre (the ellipse's, when it is one).
    outer : Circle
        The image circle.
    cutoff : Circle or None
        The self-occlusion disc; None when there is none (a fisheye).
    ellipse : Ellipse or None
        The rim as an ellipse, when it measurably is one.
    cropped_by : tuple of str
        The frame edges that cut the image circle, of ``FRAME_EDGES`` (left, top,
        right, bottom); empty when the whole circle is in the frame.
    rim_in_frame : float
        Fraction of the circle's circumference inside the frame.
    rim_seen : float
        Fraction of the rays (all around) on which the rim was found and agrees
        with the circle: at most ``rim_in_frame``, less where dark scene touches it.
    rim_polarity : str
        ``'bright inside'`` (a bright disc in a dark border); for a rim found by its
        edge of either polarity (a mirror in a bright housing), ``'dark inside'`` where
        the level steps up across it on most of the rays that step, else ``'mixed'``
        (darker inside on some arcs, brighter or a thin line on others).
    rim_arcs_deg : tuple of (start, end)
        The arcs of the rim the circle was fitted to, in image angle (deg, from +u
        towards +v), ``start < end``, ``end`` past 360 for an arc across 0 deg.
    """

    centre: tuple[float, float]
    outer: Circle
    cutoff: Circle | None
    ellipse: Ellipse | None
    cropped_by: tuple[str, ...] = ()
    rim_in_frame: float = 1.0
    rim_seen: float = 1.0
    rim_polarity: str = "bright inside"
    rim_arcs_deg: tuple[tuple[float, float], ...] = ()

    @property
    def outer_radius(self) -> float:
        return self.outer.radius

    @property
    def cutoff_radius(self) -> float | None:
        return None if self.cutoff is None else self.cutoff.radius

    def to_dict(self) -> dict[str, Any]:
        return {
            "centre": list(self.centre),
            "outer_radius": self.outer_radius,
            "cutoff_radius": self.cutoff_radius,
            "outer": self.outer.to_dict(),
            "cutoff": None if self.cutoff is None else self.cutoff.to_dict(),
            "ellipse": None if self.ellipse is None else self.ellipse.to_dict(),
            "cropped_by": list(self.cropped_by),
            "rim_in_frame": self.rim_in_frame,
            "rim_seen": self.rim_seen,
            "rim_polarity": self.rim_polarity,
            "rim_arcs_deg": [list(arc) for arc in self.rim_arcs_deg],
        }


@dataclass(frozen=True)
class _Rim:
    """A rim found: its circle, its edge points (n, 2), how many rays fall in the frame, its polarity.

    ``stepping`` counts the rays that cross a step across the circle (the levels
    just inside and just outside it differ), edge or not: what ranks candidates.
    """

    circle: Circle
    points: FloatArray
    rays_in_frame: float
    polarity: int
    stepping: int

    @property
    def convincing(self) -> bool:
        """Whether the level steps across the circle on so many rays that no other candidate is needed."""
        return self.stepping >= CONVINCING_RIM_FRACTION * self.rays_in_frame

    @property
    def rank(self) -> float:
        """Which of two rims to keep: the one with more stepping rays (with a rim's edge or line, for
        polarity 0); of dark-inside ones, the larger."""
        return self.stepping if self.polarity >= 0 else self.circle.radius
