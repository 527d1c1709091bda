"""The projection uncertainty figure of a table learned from checkerboards (mrcal's uncertainty map).

Left: the image, each pixel coloured by its 95% band (px: how far the table's pixel of a ray would move with
other corner noise of the same size), with contours at 0.5, 1 and 2 px and the boards' field between two dashed
circles. Right: each ring's band (the 95th percentile of the largest shift along it) against its angle from the
axis, the boards' field shaded, the refusal's 2 px drawn.
"""

from __future__ import annotations

import io
import math
from pathlib import Path

import numpy as np

from ..calibrate.core.projection_band import MAX_BAND_PX, ProjectionBand
from ..calibrate.core.report import table_fit_report
from ..camera.radial_models import rho_of_alpha
from ..errors import PanomapError
from ..files import write_bytes_atomic
from ..table.table import PanoMappingTable

CONTOURS_PX = (0.5, 1.0, 2.0)


def table_projection_band(table: PanoMappingTable, source: object | None = None) -> ProjectionBand:
    """The projection band a table's report holds.

    Raises
    ------
    PanomapError
        Naming ``source`` where the table holds none (a table not learned from checkerboards).
    """
    report = table_fit_report(table, source)
    band = None if report is None or report.lines is None else report.lines.projection
    if band is None:
        raise PanomapError(
            "holds no projection uncertainty: a table learned from checkerboards (fit --image) has one", source
        )
    return band


def uncertainty_plot_png(table: PanoMappingTable, band: ProjectionBand) -> bytes:
    """PNG bytes of the uncertainty map over the image and the band ring by ring."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    model = table.model
    alpha = np.radians(np.asarray(band.alpha_deg))
    phi = np.radians(np.asarray(band.azimuth_deg))
    radius = np.abs(np.asarray(model.radial(rho_of_alpha(alpha, model.axis)), dtype=float))
    pixel = np.asarray(band.pixel_band_px, dtype=float)
    closed = np.append(phi, phi[0] + 2 * math.pi)
    u = model.centre[0] + radius[:, None] * np.cos(closed)[None]
    v = model.centre[1] + radius[:, None] * np.sin(closed)[None]
    values = np.concatenate([pixel, pixel[:, :1]], axis=1)
    figure, (image, rings) = plt.subplots(
        1, 2, figsize=(12, 5.4), gridspec_kw={"width_ratios": [1.1, 1]}, constrained_layout=True
    )
    top = max(float(np.nanmax(values[np.isfinite(values)], initial=0.0)), 2.5 * MAX_BAND_PX)
    mesh = image.pcolormesh(u, v, values, shading="gouraud", cmap="viridis", vmin=0.0, vmax=min(top, 4 * MAX_BAND_PX))
    lines = image.contour(u, v, values, levels=list(CONTOURS_PX), colors="white", linewidths=0.8)
    image.clabel(lines, fmt="%.1f px", fontsize=8)
    inside = band.inside()
    for edge in (int(np.argmax(inside)), int(len(inside) - 1 - np.argmax(inside[::-1]))):
        image.plot(u[edge], v[edge], "--", color="tab:red", lw=1.2)
    if table.image_size is not None:
        image.set_xlim(0, table.image_size[0])
        image.set_ylim(table.image_size[1], 0)
    else:
        image.invert_yaxis()
    image.set_aspect("equal")
    image.set_xlabel("u (px)")
    image.set_ylabel("v (px)")
    image.set_title("95% band of each pixel (px); the boards' field between the dashed circles")
    figure.colorbar(mesh, ax=image, label="95% band (px)")
    ring = np.asarray(band.ring_band_px, dtype=float)
    rings.plot(band.alpha_deg, ring, "o-", color="tab:blue", ms=3, label="ring's band (its largest shift, 95%)")
    rings.plot(band.alpha_deg, np.median(pixel, axis=1), "-", color="tab:green", label="median pixel's band")
    rings.axvspan(*band.field_deg, color="tab:orange", alpha=0.15, label="the boards' field")
    rings.axhline(MAX_BAND_PX, color="tab:red", ls=":", label=f"refused beyond {MAX_BAND_PX:.0f} px in the field")
    worst, at_deg = band.worst_inside()
    rings.set_title(
        f"corner noise {band.sigma_px:.2f} px, {band.corners} corners on {band.boards} board(s)\nworst ring in the "
        f"field {worst:.2f} px at {at_deg:.0f} deg",
        fontsize=9,
    )
    rings.set_xlabel("angle from the axis alpha (deg)")
    rings.set_ylabel("95% band (px)")
    rings.set_ylim(0, min(max(float(np.nanmax(ring[np.isfinite(ring)], initial=0.0)) * 1.1, 2.5), 20.0))
    rings.grid(alpha=0.3)
    rings.legend(loc="upper left", fontsize=8)
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=100)
    plt.close(figure)
    return buffer.getvalue()


def save_uncertainty_plot(table: PanoMappingTable, path: str | Path, source: object | None = None) -> None:
    """Write the uncertainty figure as PNG, through a temporary file.

    Raises
    ------
    PanomapError
        Where the table holds no projection uncertainty (naming ``source``).
    """
    write_bytes_atomic(path, uncertainty_plot_png(table, table_projection_band(table, source)))
