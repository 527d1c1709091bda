"""From a fitted camera to its pano-mapping table: the radii, the range, the size and the checks.

:func:`create_table` chooses what the fit leaves open (the radii, when not
given, and the table size), checks that the radial function covers the given
annulus, fills the table (:func:`panomap.table.table.fill_entries`) and stores
in its ``info`` where each radius came from, the fit report with the radius'
standard error, and warnings where the table reaches beyond the landmarks.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import partial
from typing import Any

import numpy as np

from ... import inputs
from ...camera.uncertainty import radius_standard_error
from ...camera.valid_range import annulus_coverage_problem, valid_elevation_range
from ...errors import PanomapError
from ...geometry import TWO_PI, pixel_polar
from ...table.table import PanoMappingTable, check_table_chords, check_table_rows, check_table_size, fill_entries
from ..core.noise import rim_slack_px
from ..core.report import RadiusUncertainty
from ..core.sources import Source
from ..core.table_range import DEFAULT_MAX_SIZE, world_range
from .fit import CameraFit

# The table may reach this far beyond the landmarks' elevations before a warning says so.
EXTRAPOLATION_WARNING_DEG = 3.0


@dataclass(frozen=True)
class Annulus:
    """The visible annulus of a table, px, and where each radius came from."""

    cutoff_radius: float
    outer_radius: float
    cutoff_source: Source
    outer_source: Source


def choose_annulus(
    fit: CameraFit,
    image_size: tuple[int, int] | None,
    cutoff_radius: float | None,
    outer_radius: float | None,
    whole_frame: bool = False,
) -> Annulus:
    """The given radii (:attr:`Source.GIVEN`), or their defaults.

    The cut-off radius defaults to 0 (none); the outer radius to the largest
    circle about the centre inside the image (or reaching the farthest
    landmark, if that is further), or the farthest landmark when there is no
    image size. With ``whole_frame`` (the image was searched and shows no rim: a
    full-frame fisheye, whose picture fills the frame), it reaches the frame's
    farthest corner instead, so that every pixel of the frame is in the table
    (where f_r runs that far). A landmark reaches as far as its pixel, or as far
    as the fitted f_r puts the landmarks' highest or lowest elevation, if further
    (the fit, within the noise, may put a landmark near a corner a few pixels past
    its pixel).

    Raises
    ------
    PanomapError
        Unless 0 <= cut-off radius < outer radius, both finite.
    """
    cutoff_source = outer_source = Source.GIVEN
    if cutoff_radius is None:
        cutoff_radius, cutoff_source = 0.0, Source.DEFAULT_NONE
    if outer_radius is None:
        u0, v0 = fit.model.centre
        fitted = np.abs(fit.model.radial(np.asarray(fit.landmark_range)))
        farthest = float(np.nanmax([*pixel_polar(fit.landmarks.pixels, (u0, v0))[0], *fitted]))
        if image_size is not None and whole_frame:
            width, height = image_size
            corner = math.hypot(max(u0 + 0.5, width - 0.5 - u0), max(v0 + 0.5, height - 0.5 - v0))
            outer_radius, outer_source = max(corner, farthest), Source.DEFAULT_WHOLE_FRAME
        elif image_size is not None:
            width, height = image_size
            inscribed = min(u0 + 0.5, v0 + 0.5, width - 0.5 - u0, height - 0.5 - v0)
            outer_radius, outer_source = max(float(inscribed), farthest), Source.DEFAULT_INSIDE_IMAGE
        else:
            outer_radius, outer_source = farthest, Source.DEFAULT_FARTHEST_LANDMARK
    cutoff_radius, outer_radius = float(cutoff_radius), float(outer_radius)
    if not (math.isfinite(cutoff_radius) and math.isfinite(outer_radius)) or not 0 <= cutoff_radius < outer_radius:
        raise PanomapError(
            f"the cut-off radius ({cutoff_radius:g} px) must be >= 0 and below the outer radius ({outer_radius:g} px)"
        )
    return Annulus(cutoff_radius, outer_radius, cutoff_source, outer_source)


def create_table(
    fit: CameraFit,
    *,
    size: tuple[int, int] | None = None,
    image_size: tuple[int, int] | None = None,
    cutoff_radius: float | None = None,
    outer_radius: float | None = None,
    info: dict[str, Any] | None = None,
) -> PanoMappingTable:
    """Make the pano-mapping table of a fitted camera.

    The elevation range runs from the cut-off radius to the outer radius,
    narrowed to where f_r is monotonic and around the landmarks.

    Parameters
    ----------
    fit : CameraFit
        The landmark fit.
    size : (M, N), optional
        Default: about one entry per pixel along the image circle (M) and
        along the radius (N).
    image_size : (width, height), optional
        The omni-images' size; limits the default outer radius and marks
        pixels outside the image invalid.
    cutoff_radius : float, optional
        Radius (px) of the self-occlusion disc; default 0 (none).
    outer_radius : float, optional
        Radius (px) of the image circle; default the largest circle about the
        centre inside the image (or reaching the farthest landmark, if that is
        further), or the farthest landmark when there is no image size.
    info : dict, optional
        Stored in the table; its ``sources`` (quantity -> text) gain the
        radii's when it lacks them.

    Returns
    -------
    PanoMappingTable
    """
    inputs.instance(fit, CameraFit, "the fit", " (panomap.fit_camera makes one)")
    image_size = inputs.optional_image_size(image_size)
    annulus = choose_annulus(fit, image_size, cutoff_radius, outer_radius)
    info = inputs.info(info)
    sources = dict(info.get("sources", {})) if info else {}
    sources.setdefault("cutoff_radius", annulus.cutoff_source.value)
    sources.setdefault("outer_radius", annulus.outer_source.value)
    return table_for(fit, annulus, size=size, image_size=image_size, info=dict(info or {}) | {"sources": sources})


def table_for(
    fit: CameraFit,
    annulus: Annulus,
    *,
    size: tuple[int, int] | None,
    image_size: tuple[int, int] | None,
    info: dict[str, Any],
) -> PanoMappingTable:
    """The table of ``fit`` over ``annulus``; ``info`` (with its ``sources``) is stored as given.

    When either radius was given or detected (not a default), f_r must run monotonically
    from one to the other (from the cut-off radius only, where the outer one is a default:
    a mirror image that overfills the frame, whose cut-off disc alone was found).
    """
    cutoff_radius, outer_radius = annulus.cutoff_radius, annulus.outer_radius
    slack = rim_slack_px(fit.settings.pixel_sigma_px)
    if not (annulus.cutoff_source.is_default and annulus.outer_source.is_default):
        problem = annulus_coverage_problem(
            fit.model.radial,
            fit.landmark_range,
            cutoff_radius,
            outer_radius,
            slack,
            to_outer=not annulus.outer_source.is_default,
        )
        if problem:
            named = problem.startswith("the fitted radial function")  # (the monotonic check names it itself)
            what = "" if named else f"the fitted radial function ({fit.model.radial.kind}) "
            raise PanomapError(
                f"{what}{problem}; it must run monotonically "
                "from the cut-off radius to the image circle (try another radial model, or check the radii)"
            )
    camera_range = valid_elevation_range(
        fit.model.radial, fit.landmark_range, cutoff_radius, outer_radius, slack_px=slack
    )
    rho_s, rho_e = world_range(camera_range, fit.model)
    tilted = fit.model.rotation is not None
    ends = np.asarray(fit.model.radial(np.array([rho_s, rho_e])), dtype=np.float64)
    if not (math.isfinite(rho_s) and math.isfinite(rho_e) and np.isfinite(ends).all()):
        raise PanomapError(
            f"the fitted radial function ({fit.model.radial.kind}) gives no radius over the elevations from the "
            f"cut-off radius ({cutoff_radius:.1f} px) to the image circle ({outer_radius:.1f} px): too few landmarks, "
            "or all at a few radii; add landmarks spread over the annulus, or try another radial model"
        )
    if size is None:
        r_span = abs(float(fit.model.radial(rho_e) - fit.model.radial(rho_s)))
        reach = max(float(np.nanmax(np.abs(fit.model.radial(np.array([rho_s, rho_e]))))), 1.0)
        m = min(8 * math.ceil(TWO_PI * reach / 8), DEFAULT_MAX_SIZE[0])
        size = (max(m, 16), min(max(math.ceil(r_span), 16), DEFAULT_MAX_SIZE[1]))
    size = check_table_size(size)
    check_table_chords(size, max(float(np.nanmax(np.abs(ends))), 1.0))
    grid = partial(fill_entries, fit.model, camera_range=camera_range if tilted else None)
    check_table_rows(size, (rho_s, rho_e), grid)
    entries = grid(size, (rho_s, rho_e))
    table_info = dict(info)
    table_info["fit"] = replace(fit.report(), uncertainty=_uncertainty(fit, (rho_s, rho_e))).to_dict()
    table_info["warnings"] = _rim_notes(fit, cutoff_radius, outer_radius) + _range_warnings(
        *_data_range(fit), (rho_s, rho_e)
    )
    return PanoMappingTable(
        entries=entries,
        elevation_range=(rho_s, rho_e),
        model=fit.model,
        camera_position=fit.camera_position,
        image_size=image_size,
        cutoff_radius=cutoff_radius,
        outer_radius=outer_radius,
        info=table_info,
        camera_elevation_range=camera_range if tilted else None,
    )


def _uncertainty(fit: CameraFit, elevation_range: tuple[float, float]) -> RadiusUncertainty:
    """Standard error of f_r (px) on a grid over the table's range, and its summary."""
    rho = np.linspace(*elevation_range, 91)
    se = radius_standard_error(fit.model.radial, fit.covariance, rho)
    low, high = fit.landmark_range
    inside = (rho >= low) & (rho <= high)
    return RadiusUncertainty(
        elevation_deg=tuple(np.degrees(rho).tolist()),
        radius_se_px=tuple(se.tolist()),
        max_se_in_landmark_range_px=float(se[inside].max()) if inside.any() else None,
        max_se_px=float(se.max()),
    )


def _rim_notes(fit: CameraFit, cutoff_radius: float, outer_radius: float) -> list[str]:
    """Notes on landmarks the fit puts just beyond the annulus (within the noise allowance): kept."""
    r = fit.model.radial(fit.rho[fit.inliers])
    names = [name for name, keep in zip(fit.landmarks.names, fit.inliers, strict=True) if keep]
    notes = []
    for where, beyond in (
        ("beyond the image circle", r - outer_radius),
        ("inside the cut-off disc", cutoff_radius - r),
    ):
        over = np.flatnonzero(beyond > 1e-6)
        if over.size:
            worst = int(over[np.argmax(beyond[over])])
            notes.append(
                f"{over.size} landmark(s) lie just {where} (up to {beyond[worst]:.1f} px, {names[worst]!r}): "
                "within the pixel noise, kept; the table reaches them"
            )
    return notes


def _data_range(fit: CameraFit) -> tuple[tuple[float, float], str]:
    """The elevations (rad, camera axes) the fit's data span, and what they are: the landmarks', with the
    image's lines where they joined the fit (:mod:`panomap.calibrate.landmarks.joint`)."""
    low, high = fit.landmark_range
    if fit.lines is None:
        return (low, high), "landmark"
    lines_low, lines_high = (math.radians(x) for x in fit.lines.elevation_range_deg)
    return (min(low, lines_low), max(high, lines_high)), "landmark or line point"


def _range_warnings(landmark_range: tuple[float, float], what: str, table_range: tuple[float, float]) -> list[str]:
    """Warnings where the table reaches beyond the data's elevations (``what``: the landmarks', or also the
    lines') by more than a few degrees."""
    warnings = []
    below = math.degrees(landmark_range[0] - table_range[0])
    above = math.degrees(table_range[1] - landmark_range[1])
    if below > EXTRAPOLATION_WARNING_DEG:
        warnings.append(
            f"the table reaches {below:.1f} deg below the lowest {what} "
            f"({math.degrees(landmark_range[0]):.1f} deg): the radius there is extrapolated"
        )
    if above > EXTRAPOLATION_WARNING_DEG:
        warnings.append(
            f"the table reaches {above:.1f} deg above the highest {what} "
            f"({math.degrees(landmark_range[1]):.1f} deg): the radius there is extrapolated"
        )
    return warnings
