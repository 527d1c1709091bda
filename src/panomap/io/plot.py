"""The fit plot (the paper's Fig. 7b): the radial stretching function and the landmarks."""

from __future__ import annotations

import io
import math
from pathlib import Path
from typing import Any

import numpy as np

from ..calibrate.core.report import table_fit_report
from ..files import write_bytes_atomic
from ..table.table import PanoMappingTable


def fit_plot_png(table: PanoMappingTable) -> bytes:
    """PNG bytes of f_r over the table's elevation range, the landmarks and their residuals."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fit = table_fit_report(table)
    landmarks = () if fit is None else fit.landmarks
    u0, v0 = table.model.centre
    rho_s, rho_e = table.elevation_range
    rho = np.linspace(rho_s, rho_e, 512)
    elevation = np.array([row.elevation_deg for row in landmarks], dtype=float)
    radius = np.array([math.hypot(row.u - u0, row.v - v0) for row in landmarks], dtype=float)
    residual = np.array([row.residual_px for row in landmarks], dtype=float)

    figure, (top, bottom) = plt.subplots(
        2, 1, figsize=(7, 6), sharex=True, gridspec_kw={"height_ratios": [3, 1]}, constrained_layout=True
    )
    top.plot(np.degrees(rho), table.model.radial(rho), color="tab:blue", label=f"f_r ({table.model.radial.kind})")
    uncertainty = None if fit is None else fit.uncertainty
    if uncertainty is not None:
        band_rho = np.radians(np.asarray(uncertainty.elevation_deg))
        band = 2 * np.asarray(uncertainty.radius_se_px)
        curve = table.model.radial(band_rho)
        top.fill_between(
            np.degrees(band_rho), curve - band, curve + band, color="tab:blue", alpha=0.25, label="+-2 standard errors"
        )
    top.plot(elevation, radius, "+", color="tab:red", markersize=10, mew=2, label="landmarks")
    top.axhline(table.cutoff_radius, color="grey", lw=0.8, ls=":", label="cut-off / outer radius")
    top.axhline(table.outer_radius, color="grey", lw=0.8, ls=":")
    top.set_ylabel("image radius r (px)")
    rms, largest = (math.nan, math.nan) if fit is None else (fit.rms_px, fit.max_px)
    top.set_title(f"Radial stretching function: RMS {rms:.2f} px, max {largest:.2f} px")
    top.legend(loc="best")
    top.grid(alpha=0.3)
    bottom.bar(elevation, residual, width=max(np.ptp(np.degrees(rho)) / 150, 0.2), color="tab:red")
    bottom.set_ylabel("residual (px)")
    bottom.set_xlabel("elevation rho (deg)")
    bottom.grid(alpha=0.3)
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=100)
    plt.close(figure)
    return buffer.getvalue()


def save_fit_plot(table: PanoMappingTable, path: str | Path) -> None:
    """Write the fit plot as PNG, through a temporary file."""
    write_bytes_atomic(path, fit_plot_png(table))


def fit_curve(table: PanoMappingTable) -> dict[str, Any]:
    """The fit plot's data (Fig. 7b) as plain numbers, for drawing it elsewhere (the learning page).

    Returns
    -------
    dict
        ``elevation_deg``, ``radius_px``, ``se_px``: f_r and its standard error
        sampled over the table's elevation range; ``landmarks``: per landmark its
        ``name``, ``elevation_deg``, ``radius_px`` (distance from the fitted
        centre), ``residual_px`` and ``outlier``; ``cutoff_radius_px``,
        ``outer_radius_px``.
    """
    fit = table_fit_report(table)
    u0, v0 = table.model.centre
    uncertainty = None if fit is None else fit.uncertainty
    if uncertainty is not None:
        rho = np.radians(np.asarray(uncertainty.elevation_deg, dtype=float))
        se = np.asarray(uncertainty.radius_se_px, dtype=float)
    else:
        rho = np.linspace(*table.elevation_range, 91)
        se = np.zeros_like(rho)
    return {
        "elevation_deg": np.degrees(rho).tolist(),
        "radius_px": np.asarray(table.model.radial(rho), dtype=float).tolist(),
        "se_px": se.tolist(),
        "landmarks": [
            {
                "name": row.name,
                "elevation_deg": row.elevation_deg,
                "radius_px": math.hypot(row.u - u0, row.v - v0),
                "residual_px": row.residual_px,
                "outlier": row.outlier,
            }
            for row in (() if fit is None else fit.landmarks)
        ],
        "cutoff_radius_px": table.cutoff_radius,
        "outer_radius_px": table.outer_radius,
    }
