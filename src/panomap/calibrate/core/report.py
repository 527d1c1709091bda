"""The fit report: what :func:`panomap.calibrate.landmarks.fit.fit_camera` chose and how well it fits, typed.

A table stores it in ``info["fit"]`` as :meth:`FitReport.to_dict` writes it
(angles in degrees, residuals in px), with the radius's standard error over
the table's range added as ``"uncertainty"``; :func:`table_fit_report` reads
it back from a table.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, fields
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

import numpy as np

from ...errors import PanomapError
from ...geometry import FloatArray
from .line_report import LineFitReport

CENTRE_AS_FOUND = ", centre as found"  # ends the name of a mount that held the centre where it was found
# A fitted tilt is told from level where it is this many of its standard errors or more.
TILT_SHOWS_SE = 2.0

if TYPE_CHECKING:
    from ...table.table import PanoMappingTable


@dataclass(frozen=True)
class LandmarkResidual:
    """One landmark and where the fitted model puts it.

    Attributes
    ----------
    name : str
    u, v : float
        The landmark's pixel, px.
    X, Y, Z : float
        Its world point, world units (named as in the landmark files).
    azimuth_deg, elevation_deg : float
        Its ray from the camera, deg.
    u_fit, v_fit : float
        Where the model puts it, px.
    residual_px : float
        Distance from its pixel to that place, px.
    radial_residual_px : float
        Fitted minus measured image radius, px.
    outlier : bool
        Dropped from the fit.
    """

    name: str
    u: float
    v: float
    X: float
    Y: float
    Z: float
    azimuth_deg: float
    elevation_deg: float
    u_fit: float
    v_fit: float
    residual_px: float
    radial_residual_px: float
    outlier: bool

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: Any) -> LandmarkResidual:
        return cls(**_Reader(data, "a landmark row", cls).scalars())


@dataclass(frozen=True)
class FitSettings:
    """The noise model and options a fit used.

    Attributes
    ----------
    pixel_sigma_px : float
        Standard deviation of the landmarks' pixels, px.
    world_sigma : float
        Standard deviation of their world coordinates, world units.
    refine_centre, reject_outliers : bool
    model_requested : str
        ``"auto"`` or the radial model asked for.
    """

    pixel_sigma_px: float
    world_sigma: float
    refine_centre: bool
    reject_outliers: bool
    model_requested: str

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: Any) -> FitSettings:
        return cls(**_Reader(data, "the fit settings", cls).scalars())


@dataclass(frozen=True)
class RadiusUncertainty:
    """The standard error of f_r over a table's elevation range.

    Attributes
    ----------
    elevation_deg : tuple of float
        The elevations sampled, deg.
    radius_se_px : tuple of float
        The standard error of the radius there, px.
    max_se_in_landmark_range_px : float or None
        Its largest value between the lowest and highest landmark (None when no
        sample falls there).
    max_se_px : float
        Its largest value over the table's range.
    """

    elevation_deg: tuple[float, ...]
    radius_se_px: tuple[float, ...]
    max_se_in_landmark_range_px: float | None
    max_se_px: float

    def to_dict(self) -> dict[str, Any]:
        return {
            "elevation_deg": list(self.elevation_deg),
            "radius_se_px": list(self.radius_se_px),
            "max_se_in_landmark_range_px": self.max_se_in_landmark_range_px,
            "max_se_px": self.max_se_px,
        }

    @classmethod
    def from_dict(cls, data: Any) -> RadiusUncertainty:
        uncertainty = _Reader(data, "the radius uncertainty", cls)
        elevation = uncertainty.numbers("elevation_deg")
        se = uncertainty.numbers("radius_se_px")
        if len(se) != len(elevation):
            raise _malformed(f"the radius uncertainty has {len(elevation)} elevations and {len(se)} standard errors")
        return cls(elevation_deg=elevation, radius_se_px=se, **uncertainty.scalars())


def tilt_standard_errors(w: FloatArray, covariance: FloatArray) -> tuple[float, float]:
    """Standard errors (rad) of the tilt |w| and of the azimuth it leans toward, from w's covariance (2, 2).

    The azimuth's is infinite for a level camera (it has no direction).
    """
    norm = float(np.hypot(w[0], w[1]))
    if norm < 1e-12:
        return math.sqrt(max(float(np.trace(covariance)) / 2, 0.0)), math.inf
    along = np.array([w[0], w[1]]) / norm
    across = np.array([-w[1], w[0]]) / norm**2
    return (
        math.sqrt(max(float(along @ covariance @ along), 0.0)),
        math.sqrt(max(float(across @ covariance @ across), 0.0)),
    )


@dataclass(frozen=True)
class ViewpointReport:
    """Whether the camera has a single viewpoint, as the landmarks say (:mod:`panomap.calibrate.landmarks.viewpoint`).

    Attributes
    ----------
    single_viewpoint : bool
        Every ray leaves from O_m (the paper's model); False where cross-validation chose ray origins along
        the axis.
    excursion : float
        How far the ray origin moves along the axis over the landmarks' elevations, world units.
    parallax_px : float
        The largest error (px) a single-viewpoint table of this camera would make at a horizontal distance of
        ``parallax_distance`` (0 for a single viewpoint).
    parallax_distance : float
        World units (1: a metre, where the world is in metres).
    cross_validation : mapping of str to float
        Leave-one-out whitened RMS of the landmarks' radii of each candidate.
    """

    single_viewpoint: bool
    excursion: float
    parallax_px: float
    parallax_distance: float
    cross_validation: Mapping[str, float]

    def sentences(self) -> list[str]:
        """The report in lines, as ``fit`` and ``info`` print it."""
        scores = ", ".join(f"{name} {value:.3f}" for name, value in self.cross_validation.items())
        held_out = f" (held-out whitened RMS: {scores})" if scores else ""
        if self.single_viewpoint:
            return [f"viewpoint: single (every ray from O_m){held_out}"]
        return [
            f"viewpoint: not single: the rays leave the axis over {self.excursion:.4g} world units "
            f"({1000 * self.excursion:.1f} mm where the world is in metres) over the landmarks' elevations, "
            f"as a mirror of revolution's caustic{held_out}",
            f"a single-viewpoint table would be up to {self.parallax_px:.2f} px off at a distance of "
            f"{self.parallax_distance:g}; views at a distance (cylinder, plane, floor, project, unproject --z) "
            "use each ray's own origin",
        ]

    def to_dict(self) -> dict[str, Any]:
        data = {f.name: getattr(self, f.name) for f in fields(self)}
        data["cross_validation"] = dict(self.cross_validation)
        return data

    @classmethod
    def from_dict(cls, data: Any) -> ViewpointReport:
        report = _Reader(data, "the viewpoint", cls)
        scores = report.mapping("cross_validation")
        if not all(_is_number(value) for value in scores.values()):
            raise _malformed("a cross-validation score of the viewpoint is not a number")
        return cls(cross_validation={str(k): float(v) for k, v in scores.items()}, **report.scalars())


@dataclass(frozen=True)
class MountReport:
    """How the camera is mounted, as fitted: its tilt off the vertical and its position.

    Attributes
    ----------
    tilt_mode : {"fit", "none", "given"}
        What was done: the tilt estimated (and kept or not), the camera taken as level (asked
        for, or a model that takes the paper's vertical axis), or a given tilt.
    tilt_deg : float
        Angle of the optical axis off the vertical, deg (0 for a level camera).
    toward_deg : float
        World azimuth toward which the optical axis leans, deg.
    tilt_se_deg, toward_se_deg : float or None
        Their standard errors, deg (None when the tilt was not fitted, or has no direction).
    tilt_fitted : bool
        The tilt was estimated and kept (cross-validation chose it).
    camera_given : (X0, Y0, Z0)
        The position given (the tape measurement), world units.
    camera : (X0, Y0, Z0)
        The position used: refined when ``position_refined``.
    camera_sigma : float
        The given position's standard deviation on each coordinate, world units (0: exact).
    position_refined : bool
    chosen : str
        The mount chosen: ``"level, position as given"``, ``"tilt"``, ``"position"`` or ``"tilt + position"``;
        ``"tilt, centre as found"`` where the centre was to be refined but a tilt about the centre found in the
        image predicted the held-out landmarks better than the level fit's moved centre.
    cross_validation : mapping of str to float
        Each mount tried and its held-out RMS error in sigmas (smaller is better); empty when no
        mount lowered the chi-square beyond chance, so that none needed cross-validating.
    """

    tilt_mode: str
    tilt_deg: float
    toward_deg: float
    tilt_se_deg: float | None
    toward_se_deg: float | None
    tilt_fitted: bool
    camera_given: tuple[float, float, float]
    camera: tuple[float, float, float]
    camera_sigma: float
    position_refined: bool
    chosen: str
    cross_validation: Mapping[str, float]

    def __post_init__(self) -> None:
        object.__setattr__(self, "cross_validation", MappingProxyType(dict(self.cross_validation)))

    @property
    def camera_shift(self) -> float:
        """How far (world units) the fit moved the camera from the given position."""
        return math.dist(self.camera, self.camera_given)

    @property
    def tilt_shows(self) -> bool:
        """Whether the fitted tilt is told from level: TILT_SHOWS_SE of its standard errors or more (a tilt of
        0.05 +- 0.16 deg about the rim's centre is a level camera, its centre where the rim puts it)."""
        return self.tilt_se_deg is None or self.tilt_deg >= TILT_SHOWS_SE * self.tilt_se_deg

    def sentences(self) -> list[str]:
        """The tilt and the camera position as fitted, in a line each (a level camera at its given place: none)."""
        lines = []
        if self.tilt_deg > 0:
            how = {"fit": "fitted", "given": "given"}.get(self.tilt_mode, self.tilt_mode)
            spread = ""
            if self.tilt_se_deg is not None:
                toward_se = "" if self.toward_se_deg is None else f" +- {self.toward_se_deg:.1f}"
                spread = f" +- {self.tilt_se_deg:.2f}"
                lines.append(
                    f"tilt ({how}): the optical axis is {self.tilt_deg:.2f}{spread} deg off the vertical, leaning "
                    f"toward azimuth {self.toward_deg:.1f}{toward_se} deg"
                )
            else:
                lines.append(
                    f"tilt ({how}): the optical axis is {self.tilt_deg:.2f} deg off the vertical, leaning toward "
                    f"azimuth {self.toward_deg:.1f} deg"
                )
        elif self.tilt_mode == "fit":
            lines.append("tilt: none (the landmarks do not show one beyond their noise)")
        if self.position_refined:
            x, y, z = self.camera
            lines.append(
                f"camera position refined with the landmarks: ({x:.4g}, {y:.4g}, {z:.4g}), "
                f"{self.camera_shift:.3g} from the given one (its sigma {self.camera_sigma:.3g} a coordinate)"
            )
        return lines

    def to_dict(self) -> dict[str, Any]:
        data = {f.name: getattr(self, f.name) for f in fields(self)}
        data["cross_validation"] = dict(self.cross_validation)
        data["camera_given"], data["camera"] = list(self.camera_given), list(self.camera)
        return data

    @classmethod
    def from_dict(cls, data: Any) -> MountReport:
        mount = _Reader(data, "the mount", cls)
        given, camera = mount.numbers("camera_given"), mount.numbers("camera")
        if len(given) != 3 or len(camera) != 3:
            raise _malformed("a camera position of the mount is not three numbers")
        scores = mount.mapping("cross_validation")
        if not all(_is_number(value) for value in scores.values()):
            raise _malformed("a cross-validation score of the mount is not a number")
        return cls(
            camera_given=(given[0], given[1], given[2]),
            camera=(camera[0], camera[1], camera[2]),
            cross_validation={str(k): float(v) for k, v in scores.items()},
            **mount.scalars(),
        )


@dataclass(frozen=True)
class FitReport:
    """What a camera fit chose and how well it fits the landmarks.

    Attributes
    ----------
    model : str
        The radial model kind chosen.
    axis : {"down", "up"}
    axis_source : {"given", "detected"}
    azimuth_mode : {"fit", "paper"}
    s : {+1, -1}
    phi0_deg : float
    centre : (u0, v0)
        The image centre, px (refined, when the fit refined it).
    azimuth_consistency : float
        Weighted mean resultant length (0..1) of ``phi - s*theta``.
    rms_px, max_px : float
        RMS and largest residual over the inliers, px.
    outliers : tuple of str
        Names of the landmarks dropped.
    landmark_elevation_range_deg : (low, high)
        Lowest and highest inlier elevation, deg.
    model_selection_loo_rms_px : mapping of str to float or None
        Leave-one-out RMS residual (px) of each candidate model (None where it
        could not serve); empty when the model was forced.
    covariance : tuple of tuple of float
        Covariance (p, p) of the radial model's coefficients.
    settings : FitSettings
    landmarks : tuple of LandmarkResidual
        Every landmark, outliers included, in the order given.
    uncertainty : RadiusUncertainty or None
        The radius's standard error over a table's range: added when a table
        is made from the fit.
    centre_start : (u0, v0) or None
        The centre the fit started from, px (None in tables made before it was
        recorded); ``centre`` differs from it when the fit refined the centre.
    mount : MountReport or None
        The camera's tilt and position as fitted (None in tables made before
        they were fitted, and for the paper's model).
    lines : LineFitReport or None
        The straight lines a camera learned from lines was fitted to (None for
        a landmark fit); its ``azimuth_mode`` is then ``"lines"``.
    viewpoint : ViewpointReport or None
        Whether the camera has a single viewpoint (None where it was not tried: tables made before, fits
        with lines or forced models).
    """

    model: str
    axis: str
    axis_source: str
    azimuth_mode: str
    s: int
    phi0_deg: float
    centre: tuple[float, float]
    azimuth_consistency: float
    rms_px: float
    max_px: float
    outliers: tuple[str, ...]
    landmark_elevation_range_deg: tuple[float, float]
    model_selection_loo_rms_px: Mapping[str, float | None]
    covariance: tuple[tuple[float, ...], ...]
    settings: FitSettings
    landmarks: tuple[LandmarkResidual, ...]
    uncertainty: RadiusUncertainty | None = None
    centre_start: tuple[float, float] | None = None
    mount: MountReport | None = None
    lines: LineFitReport | None = None
    viewpoint: ViewpointReport | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "model_selection_loo_rms_px", MappingProxyType(dict(self.model_selection_loo_rms_px)))

    def centre_sentence(self) -> str | None:
        """Where the refined centre went, in a line (None when the centre was not refined)."""
        if not self.settings.refine_centre or self.centre_start is None:
            return None
        u0, v0 = self.centre
        if self.mount is not None and self.mount.chosen.endswith(CENTRE_AS_FOUND):
            if not self.mount.tilt_shows:
                return f"centre kept where it was found: ({u0:.2f}, {v0:.2f}); the landmarks do not ask to move it"
            return (
                f"centre kept where it was found: ({u0:.2f}, {v0:.2f}); a tilt of the axis predicts the landmarks "
                "better than moving it"
            )
        us, vs = self.centre_start
        joined = " and the image's lines" if self.lines is not None and self.azimuth_mode != "lines" else ""
        return (
            f"centre refined with the landmarks{joined}: ({u0:.2f}, {v0:.2f}), "
            f"{math.hypot(u0 - us, v0 - vs):.2f} px from the start ({us:.2f}, {vs:.2f})"
        )

    def to_dict(self) -> dict[str, Any]:
        """The report as plain data, in the layout a table file stores (``uncertainty`` only when known)."""
        data: dict[str, Any] = {
            "model": self.model,
            "axis": self.axis,
            "axis_source": self.axis_source,
            "azimuth_mode": self.azimuth_mode,
            "s": self.s,
            "phi0_deg": self.phi0_deg,
            "centre": list(self.centre),
            "azimuth_consistency": self.azimuth_consistency,
            "rms_px": self.rms_px,
            "max_px": self.max_px,
            "outliers": list(self.outliers),
            "landmark_elevation_range_deg": list(self.landmark_elevation_range_deg),
            "model_selection_loo_rms_px": dict(self.model_selection_loo_rms_px),
            "covariance": [list(row) for row in self.covariance],
            "settings": self.settings.to_dict(),
            "landmarks": [row.to_dict() for row in self.landmarks],
        }
        if self.centre_start is not None:
            data["centre_start"] = list(self.centre_start)
        if self.mount is not None:
            data["mount"] = self.mount.to_dict()
        if self.uncertainty is not None:
            data["uncertainty"] = self.uncertainty.to_dict()
        if self.lines is not None:
            data["lines"] = self.lines.to_dict()
        if self.viewpoint is not None:
            data["viewpoint"] = self.viewpoint.to_dict()
        return data

    @classmethod
    def from_dict(cls, data: Any) -> FitReport:
        """Read a report back, as a table file stores it.

        Raises
        ------
        PanomapError
            If an entry is missing, unexpected or of the wrong type.
        """
        report = _Reader(
            data, "the fit report", cls, optional=("uncertainty", "centre_start", "mount", "lines", "viewpoint")
        )
        selection = report.mapping("model_selection_loo_rms_px")
        for name, value in selection.items():
            if value is not None and not _is_number(value):
                raise _malformed(f"the selection score of {name!r} is {value!r}")
        covariance = tuple(_numbers(row, "a covariance row") for row in report.items("covariance"))
        if any(len(row) != len(covariance) for row in covariance):
            raise _malformed("the covariance is not a square matrix")
        centre = report.numbers("centre")
        elevation_range = report.numbers("landmark_elevation_range_deg")
        if len(centre) != 2 or len(elevation_range) != 2:
            raise _malformed("the centre or the elevation range is not a pair")
        scalars = report.scalars()
        if scalars["s"] not in (1, -1):
            raise _malformed(f"s is {scalars['s']}, not +1 or -1")
        uncertainty = data.get("uncertainty")
        start = None if data.get("centre_start") is None else _numbers(data["centre_start"], "the starting centre")
        if start is not None and len(start) != 2:
            raise _malformed("the starting centre is not a pair")
        return cls(
            centre_start=None if start is None else (start[0], start[1]),
            centre=(centre[0], centre[1]),
            outliers=tuple(_text(name, "an outlier's name") for name in report.items("outliers")),
            landmark_elevation_range_deg=(elevation_range[0], elevation_range[1]),
            model_selection_loo_rms_px={
                str(name): None if value is None else float(value) for name, value in selection.items()
            },
            covariance=covariance,
            settings=FitSettings.from_dict(data["settings"]),
            landmarks=tuple(LandmarkResidual.from_dict(row) for row in report.items("landmarks")),
            uncertainty=None if uncertainty is None else RadiusUncertainty.from_dict(uncertainty),
            mount=None if data.get("mount") is None else MountReport.from_dict(data["mount"]),
            lines=None if data.get("lines") is None else LineFitReport.from_dict(data["lines"]),
            viewpoint=None if data.get("viewpoint") is None else ViewpointReport.from_dict(data["viewpoint"]),
            **scalars,
        )


def table_fit_report(table: PanoMappingTable, source: object | None = None) -> FitReport | None:
    """The fit report a table holds (None for a table made without a fit).

    Raises
    ------
    PanomapError
        If the table's report is malformed, naming ``source`` (the table's file) where given.
    """
    data = table.info.get("fit")
    try:
        return None if data is None else FitReport.from_dict(data)
    except PanomapError as exc:
        if source is None or exc.source is not None:
            raise
        raise PanomapError(exc.detail, source) from None


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _malformed(detail: str) -> PanomapError:
    return PanomapError(f"the fit report is malformed ({detail})")


def _numbers(values: Any, what: str) -> tuple[float, ...]:
    if not isinstance(values, list) or not all(_is_number(v) for v in values):
        raise _malformed(f"{what} is not a list of numbers")
    return tuple(float(v) for v in values)


def _text(value: Any, what: str) -> str:
    if not isinstance(value, str):
        raise _malformed(f"{what} is not text")
    return value


class _Reader:
    """Typed access to one JSON object of the report; every failure is a PanomapError saying where."""

    def __init__(self, data: Any, what: str, cls: type, optional: tuple[str, ...] = ()) -> None:
        self.fields = [f for f in fields(cls) if f.name not in optional]
        keys = [f.name for f in self.fields]
        if not isinstance(data, dict):
            raise _malformed(f"{what} is not an object")
        missing = [key for key in keys if key not in data]
        if missing:
            raise _malformed(f"{what} lacks {', '.join(missing)}")
        unexpected = [str(key) for key in data if key not in keys and key not in optional]
        if unexpected:
            raise _malformed(f"{what} has unexpected entries {', '.join(unexpected)}")
        self.data: dict[str, Any] = data
        self.what = what

    def _where(self, key: str) -> str:
        return f"{key!r} in {self.what}"

    def _typed(self, key: str, types: type | tuple[type, ...], kind: str) -> Any:
        """The value at ``key`` if it is of ``types`` (True and False are not numbers)."""
        value = self.data[key]
        if not isinstance(value, types) or (isinstance(value, bool) and types is not bool):
            raise _malformed(f"{self._where(key)} is not {kind}")
        return value

    def number(self, key: str) -> float:
        return float(self._typed(key, (int, float), "a number"))

    def optional_number(self, key: str) -> float | None:
        return None if self.data[key] is None else self.number(key)

    def integer(self, key: str) -> int:
        return int(self._typed(key, int, "an integer"))

    def flag(self, key: str) -> bool:
        return bool(self._typed(key, bool, "true or false"))

    def text(self, key: str) -> str:
        return _text(self.data[key], self._where(key))

    def items(self, key: str) -> list[Any]:
        return list(self._typed(key, list, "a list"))

    def mapping(self, key: str) -> dict[Any, Any]:
        return dict(self._typed(key, dict, "an object"))

    def numbers(self, key: str) -> tuple[float, ...]:
        return _numbers(self.data[key], self._where(key))

    def scalars(self) -> dict[str, Any]:
        """The fields of a scalar type (a number, text, true or false), read by their names."""
        read = {
            "float": self.number,
            "float | None": self.optional_number,
            "int": self.integer,
            "bool": self.flag,
            "str": self.text,
        }
        return {f.name: read[str(f.type)](f.name) for f in self.fields if str(f.type) in read}
