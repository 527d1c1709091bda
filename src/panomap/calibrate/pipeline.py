"""From landmarks to a pano-mapping table: the one path ``panomap fit`` and ``panomap learn`` share.

Both call :func:`fit_table`, so a table saved from the browser is the table
``panomap fit`` makes from the same landmarks, camera position, centre and radii.
"""

from __future__ import annotations

from typing import Any

from ..table.table import PanoMappingTable, create_table
from .fit import fit_camera
from .landmarks import Landmarks


def fit_table(
    landmarks: Landmarks,
    camera_position: tuple[float, float, float],
    centre: tuple[float, float],
    *,
    image_size: tuple[int, int] | None = None,
    cutoff_radius: float | None = None,
    outer_radius: float | None = None,
    table_size: tuple[int, int] | None = None,
    model: str = "auto",
    azimuth: str = "fit",
    axis: str | None = None,
    refine_centre: bool = False,
    pixel_sigma: float = 1.0,
    world_sigma: float | None = None,
    reject_outliers: bool = True,
    info: dict[str, Any] | None = None,
) -> PanoMappingTable:
    """Fit the camera (:func:`panomap.fit_camera`) and fill its table (:func:`panomap.create_table`).

    Parameters
    ----------
    landmarks : Landmarks
        At least 5 pairs.
    camera_position : (X0, Y0, Z0)
        World units.
    centre : (u0, v0)
        Image centre, px.
    image_size : (width, height), optional
    cutoff_radius, outer_radius : float, optional
        The visible annulus, px; when both are given, automatic model choice
        only takes models that run monotonically across it.
    table_size : (M, N), optional
        Default: about one entry per pixel.
    model, azimuth, axis, refine_centre, pixel_sigma, world_sigma, reject_outliers
        As :func:`panomap.fit_camera`.
    info : dict, optional
        Provenance stored in the table (``sources``, ``image_circles``).

    Raises
    ------
    PanomapError
        From the fit or the table, saying why.
    """
    annulus = None if cutoff_radius is None or outer_radius is None else (cutoff_radius, outer_radius)
    camera_fit = fit_camera(
        landmarks,
        camera_position,
        centre,
        model=model,
        azimuth=azimuth,
        axis=axis,
        image_size=image_size,
        annulus=annulus,
        refine_centre=refine_centre,
        pixel_sigma=pixel_sigma,
        world_sigma=world_sigma,
        reject_outliers=reject_outliers,
    )
    return create_table(
        camera_fit,
        size=table_size,
        image_size=image_size,
        cutoff_radius=cutoff_radius,
        outer_radius=outer_radius,
        info=info,
    )
