"""The pano-mapping table of a camera learned from lines: as :func:`panomap.calibrate.landmarks.table.create_table`
makes it for landmarks, with the line fit's report in place of the landmarks'.

Convention: radii px, elevations rad (deg in the report); the table spans the annulus from the cut-off
disc (or the axis) to the image circle, where f_r rises monotonically.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ...camera.radial_models import rho_of_alpha
from ...camera.uncertainty import radius_standard_error
from ...errors import PanomapError
from ...geometry import TWO_PI
from ...table.table import PanoMappingTable, check_table_size, fill_entries
from ..core.report import FitReport, FitSettings, RadiusUncertainty
from ..core.table_range import DEFAULT_MAX_SIZE, world_range
from .fit import LineFit

# A standard error of the radius beyond this (px) anywhere in the table is said: on one image of the real sets,
# every fit worse than 20 px had one over 3 px (several better ones too).
LOOSE_RADIUS_PX = 3.0
# The camera position of a table learned from lines: lines know no distance; --camera-height sets Z0.
ORIGIN = (0.0, 0.0, 0.0)


def create_line_table(
    fit: LineFit,
    *,
    cutoff_radius: float,
    outer_radius: float,
    image_size: tuple[int, int] | None,
    camera_height: float | None = None,
    info: dict[str, Any] | None = None,
) -> PanoMappingTable:
    """The table of ``fit`` over the annulus ``[cutoff_radius, outer_radius]`` (px).

    ``camera_height`` (world units above the floor, Z = 0) sets the camera position (0, 0, H); without it
    the position is the origin and ``info["camera_height_known"]`` is False (views at a distance say so).

    Raises
    ------
    PanomapError
        If f_r does not run monotonically across the lines' elevations.
    """
    model = fit.model
    camera_range = fit.camera_range(cutoff_radius, outer_radius)
    rho_s, rho_e = world_range(camera_range, model)
    tilted = model.rotation is not None
    reach = max(float(np.nanmax(np.abs(model.radial(np.array(camera_range))))), 1.0)
    r_span = abs(float(model.radial(camera_range[1]) - model.radial(camera_range[0])))
    size = check_table_size(
        (
            max(min(8 * math.ceil(TWO_PI * reach / 8), DEFAULT_MAX_SIZE[0]), 16),
            min(max(math.ceil(r_span), 16), DEFAULT_MAX_SIZE[1]),
        )
    )
    entries = fill_entries(model, size, (rho_s, rho_e), camera_range=camera_range if tilted else None)
    table_info = dict(info or {})
    table_info.setdefault(
        "sources",
        {
            "camera_position": "given (--camera-height)"
            if camera_height is not None
            else "unknown (lines know no distance)",
            "centre": "fitted to the lines",
            "cutoff_radius": "detected",
            "outer_radius": "detected",
        },
    )
    report = line_fit_report(fit, (rho_s, rho_e))
    table_info["fit"] = report.to_dict()
    table_info["camera_height_known"] = camera_height is not None
    table_info.setdefault("warnings", [])
    table_info["warnings"] = list(table_info["warnings"]) + [
        sentence for sentence in fit.report.sentences() if sentence.startswith("no line between")
    ]
    loose = report.uncertainty.max_se_px if report.uncertainty is not None else None
    if loose is not None and loose > LOOSE_RADIUS_PX:
        table_info["warnings"].append(
            f"the radius is pinned loosely: its standard error reaches {loose:.1f} px (on real images the error "
            "is up to several times it); add pictures: "
            + ("the board near and far, tilted, across the annulus" if fit.report.boards else "more straight edges")
        )
    position = ORIGIN if camera_height is None else (0.0, 0.0, float(camera_height))
    if camera_height is not None and not (math.isfinite(camera_height) and camera_height > 0):
        raise PanomapError(f"the camera height must be a positive number, not {camera_height!r}")
    return PanoMappingTable(
        entries=entries,
        elevation_range=(rho_s, rho_e),
        model=model,
        camera_position=position,
        image_size=image_size,
        cutoff_radius=cutoff_radius,
        outer_radius=outer_radius,
        info=table_info,
        camera_elevation_range=camera_range if tilted else None,
    )


def line_fit_report(fit: LineFit, elevation_range: tuple[float, float]) -> FitReport:
    """The fit report a table stores: the landmark report's fields, no landmarks, the lines' report."""
    model = fit.model
    report = fit.report
    rho = np.linspace(*elevation_range, 91)
    se = radius_standard_error(model.radial, fit.covariance, rho)
    if fit.band is not None and fit.band.alpha_deg.size:
        # the picture's own evidence (:mod:`.agreement`): the jackknife over folds of lines and the cameras it
        # cannot rule out, at the rings; the Jacobian's alone where none lies (the rings' ends held beyond them)
        rings_rho = np.degrees(rho_of_alpha(np.radians(fit.band.alpha_deg), model.axis))
        order = np.argsort(rings_rho)
        honest = np.nan_to_num(fit.band.se_px(fit.jacobian_se_px()), posinf=1e6)
        se = np.maximum(se, np.interp(np.degrees(rho), rings_rho[order], honest[order]))
    low, high = report.elevation_range_deg
    inside = (np.degrees(rho) >= low) & (np.degrees(rho) <= high)
    return FitReport(
        model=model.radial.kind,
        axis=model.axis,
        axis_source="given",
        azimuth_mode="lines",
        s=model.s,
        phi0_deg=math.degrees(model.phi0),
        centre=model.centre,
        azimuth_consistency=1.0,
        rms_px=report.rms_px,
        max_px=report.max_px,
        outliers=(),
        landmark_elevation_range_deg=report.elevation_range_deg,
        model_selection_loo_rms_px=report.model_selection_cv_rms_px,
        covariance=tuple(tuple(float(x) for x in row) for row in fit.covariance),
        settings=FitSettings(report.sigma_px, 0.0, True, False, report.model),
        landmarks=(),
        uncertainty=RadiusUncertainty(
            elevation_deg=tuple(np.degrees(rho).tolist()),
            radius_se_px=tuple(se.tolist()),
            max_se_in_landmark_range_px=float(se[inside].max()) if inside.any() else None,
            max_se_px=float(se.max()),
        ),
        lines=report,
    )
