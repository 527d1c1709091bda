"""What the line fit saw: every line used with its residual, the arcs set aside and why, the gaps.

Convention: residuals in px, elevations in deg in the camera's axes (where f_r applies).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...errors import PanomapError
from ...geometry import FloatArray
from .projection_band import ProjectionBand
from .term_choice import TermChoice

# Elevation bands (deg) are looked at this wide; a band with no line point is a gap.
BAND_DEG = 5.0


@dataclass(frozen=True)
class FittedLine:
    """One straight line the fit used.

    Attributes
    ----------
    arcs : tuple of int
        The arcs (indices into the arcs given) merged into it: pieces of one line.
    image_index : int
    points : int
        Edge points used.
    rms_px, max_px : float
        RMS and largest distance of its points from its plane's image under the fitted camera.
    family : int or None
        The family of parallel lines it belongs to (index), None if none.
    elevation_deg : (low, high)
        The elevations its points span (camera axes).
    """

    arcs: tuple[int, ...]
    image_index: int
    points: int
    rms_px: float
    max_px: float
    family: int | None
    elevation_deg: tuple[float, float]

    def to_dict(self) -> dict[str, Any]:
        return {
            "arcs": list(self.arcs),
            "image_index": self.image_index,
            "points": self.points,
            "rms_px": self.rms_px,
            "max_px": self.max_px,
            "family": self.family,
            "elevation_deg": list(self.elevation_deg),
        }

    @classmethod
    def from_dict(cls, data: Any) -> FittedLine:
        try:
            low, high = data["elevation_deg"]
            family = data["family"]
            return cls(
                tuple(int(a) for a in data["arcs"]),
                int(data["image_index"]),
                int(data["points"]),
                float(data["rms_px"]),
                float(data["max_px"]),
                None if family is None else int(family),
                (float(low), float(high)),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise PanomapError(f"the line fit report is malformed ({exc})") from None


@dataclass(frozen=True)
class RejectedArc:
    """An arc the fit set aside: its index, image, why, and its RMS distance (px) from its best plane."""

    arc: int
    image_index: int
    reason: str
    rms_px: float

    def to_dict(self) -> dict[str, Any]:
        return {"arc": self.arc, "image_index": self.image_index, "reason": self.reason, "rms_px": self.rms_px}

    @classmethod
    def from_dict(cls, data: Any) -> RejectedArc:
        try:
            return cls(int(data["arc"]), int(data["image_index"]), str(data["reason"]), float(data["rms_px"]))
        except (KeyError, TypeError, ValueError) as exc:
            raise PanomapError(f"the line fit report is malformed ({exc})") from None


@dataclass(frozen=True)
class LineFitReport:
    """The line fit's account of itself.

    Attributes
    ----------
    model : str
        The radial kind chosen.
    sigma_px : float
        The edge points' noise (px), from the residuals.
    lines : tuple of FittedLine
    rejected : tuple of RejectedArc
    families : int
        Families of parallel lines found.
    vertical_lines : int
        Lines of the vertical family (0: the tilt was not learned; the camera is taken as level).
    model_selection_cv_rms_px : mapping of str to float or None
        Held-out RMS (px) of each candidate kind (cross-validation over lines); empty when forced.
    elevation_range_deg : (low, high)
        The elevations (camera axes) the lines span.
    empty_bands_deg : tuple of (low, high)
        Elevation bands of the annulus with no line point.
    azimuth_source, handedness_source : str
        Where the azimuth origin and the handedness came from (lines know neither).
    boards, corners : int
        Checkerboards and their inner corners the camera was learned from (0: learned from edge arcs);
        ``lines`` are then the boards' rows and columns, each with its corners' residuals.
    corner_rms_px : float
        RMS distance (px) of the corners from their projection (boards only).
    board_axis_deg : tuple of float
        Each board's face: the angle (deg) of its normal from the camera's axis (boards only; 0: flat under a
        camera looking down or up, square before one looking ahead).
    terms : TermChoice or None
        The image terms beyond the radial law the boards' camera kept and why (boards only).
    projection : ProjectionBand or None
        The table's 95% band under the corners' noise, ring by ring (boards only; :mod:`.projection_band`).
    """

    model: str
    sigma_px: float
    lines: tuple[FittedLine, ...]
    rejected: tuple[RejectedArc, ...]
    families: int
    vertical_lines: int
    model_selection_cv_rms_px: Mapping[str, float | None]
    elevation_range_deg: tuple[float, float]
    empty_bands_deg: tuple[tuple[float, float], ...]
    azimuth_source: str
    handedness_source: str
    boards: int = 0
    corners: int = 0
    corner_rms_px: float = 0.0
    board_axis_deg: tuple[float, ...] = ()
    terms: TermChoice | None = None
    projection: ProjectionBand | None = None

    @property
    def rms_px(self) -> float:
        """RMS distance (px) over every line's points."""
        total = sum(line.rms_px**2 * line.points for line in self.lines)
        return math.sqrt(total / max(sum(line.points for line in self.lines), 1))

    @property
    def max_px(self) -> float:
        return max((line.max_px for line in self.lines), default=0.0)

    def sentences(self) -> list[str]:
        """The report in a few lines, for the terminal."""
        if self.boards:
            return self._board_sentences()
        out = [
            f"learned from {len(self.lines)} straight lines ({sum(len(x.arcs) for x in self.lines)} arcs; "
            f"{len(self.rejected)} set aside), {self.families} famil{'y' if self.families == 1 else 'ies'} "
            f"of parallel lines; radial model {self.model}",
            f"line residuals: RMS {self.rms_px:.2f} px, max {self.max_px:.2f} px; edge noise {self.sigma_px:.2f} px",
            "tilt from "
            + (f"{self.vertical_lines} vertical lines" if self.vertical_lines else "no vertical lines: taken as level"),
        ]
        reasons: dict[str, int] = {}
        for arc in self.rejected:
            reasons[arc.reason.split(" (")[0]] = reasons.get(arc.reason.split(" (")[0], 0) + 1
        out += [f"set aside: {count} arc(s) {reason}" for reason, count in reasons.items()]
        out += [band_sentence(band) for band in self.empty_bands_deg]
        return out

    def _board_sentences(self) -> list[str]:
        out = [
            f"learned from {self.boards} checkerboard{'s' if self.boards != 1 else ''}: {self.corners} inner corners "
            f"on {len(self.lines)} straight, evenly spaced rows and columns; radial model {self.model}",
            f"corner residuals: RMS {self.corner_rms_px:.2f} px, max {self.max_px:.2f} px",
            f"tilt from {self.vertical_lines} vertical lines of the images"
            if self.vertical_lines
            else "tilt: no vertical lines (boards do not show the vertical); the camera is taken as level",
        ]
        if self.board_axis_deg:
            out.append(
                f"boards' faces {min(self.board_axis_deg):.0f}-{max(self.board_axis_deg):.0f} deg from the camera's "
                "axis (0: flat under it or square before it; boards that all face it pin no scale)"
            )
        if self.terms is not None:
            out.append(self.terms.sentence())
        if self.projection is not None:
            out += self.projection.sentences()
        out += [f"set aside: {arc.reason}" for arc in self.rejected]
        out += [band_sentence(band) for band in self.empty_bands_deg]
        return out

    def to_dict(self) -> dict[str, Any]:
        return (
            {
                "boards": self.boards,
                "corners": self.corners,
                "corner_rms_px": self.corner_rms_px,
                "board_axis_deg": list(self.board_axis_deg),
                "model": self.model,
                "sigma_px": self.sigma_px,
                "lines": [line.to_dict() for line in self.lines],
                "rejected": [arc.to_dict() for arc in self.rejected],
                "families": self.families,
                "vertical_lines": self.vertical_lines,
                "model_selection_cv_rms_px": dict(self.model_selection_cv_rms_px),
                "elevation_range_deg": list(self.elevation_range_deg),
                "empty_bands_deg": [list(band) for band in self.empty_bands_deg],
                "azimuth_source": self.azimuth_source,
                "handedness_source": self.handedness_source,
            }
            | ({} if self.terms is None else {"terms": self.terms.to_dict()})
            | ({} if self.projection is None else {"projection": self.projection.to_dict()})
        )

    @classmethod
    def from_dict(cls, data: Any) -> LineFitReport:
        try:
            low, high = data["elevation_range_deg"]
            return cls(
                model=str(data["model"]),
                sigma_px=float(data["sigma_px"]),
                lines=tuple(FittedLine.from_dict(x) for x in data["lines"]),
                rejected=tuple(RejectedArc.from_dict(x) for x in data["rejected"]),
                families=int(data["families"]),
                vertical_lines=int(data["vertical_lines"]),
                model_selection_cv_rms_px={
                    str(k): None if v is None else float(v) for k, v in dict(data["model_selection_cv_rms_px"]).items()
                },
                elevation_range_deg=(float(low), float(high)),
                empty_bands_deg=tuple((float(a), float(b)) for a, b in data["empty_bands_deg"]),
                azimuth_source=str(data["azimuth_source"]),
                handedness_source=str(data["handedness_source"]),
                boards=int(data.get("boards", 0)),
                corners=int(data.get("corners", 0)),
                corner_rms_px=float(data.get("corner_rms_px", 0.0)),
                board_axis_deg=tuple(float(a) for a in data.get("board_axis_deg", ())),
                terms=None if data.get("terms") is None else TermChoice.from_dict(data["terms"]),
                projection=None if data.get("projection") is None else ProjectionBand.from_dict(data["projection"]),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise PanomapError(f"the line fit report is malformed ({exc})") from None


def empty_bands(rho_deg: FloatArray, annulus_deg: tuple[float, float]) -> tuple[tuple[float, float], ...]:
    """Bands (deg) of ``annulus_deg`` (camera elevations, low to high) that no line point ``rho_deg`` reaches.

    The annulus is cut into bands about ``BAND_DEG`` wide; runs of empty ones are joined.
    """
    low, high = annulus_deg
    count = max(1, round((high - low) / BAND_DEG))
    edges = np.linspace(low, high, count + 1)
    filled, _ = np.histogram(rho_deg, bins=edges)
    bands: list[tuple[float, float]] = []
    for k in np.flatnonzero(filled == 0):
        if bands and math.isclose(bands[-1][1], float(edges[k])):
            bands[-1] = (bands[-1][0], float(edges[k + 1]))
        else:
            bands.append((float(edges[k]), float(edges[k + 1])))
    return tuple(bands)


def band_sentence(band: tuple[float, float]) -> str:
    """Which band has no line, and what picture would fill it."""
    low, high = band
    if high <= -45.0:
        fill = "straight edges below the camera, near the image centre: floor tiles, a rug's or a board's edges"
    elif low >= 45.0:
        fill = "straight edges above the camera: ceiling panels, beams, a board held overhead"
    else:
        fill = "straight edges near the camera's own height: door and window frames, shelves, a board at its height"
    return f"no line between {low:.0f} and {high:.0f} deg elevation: the radius there is interpolated; {fill}"
