"""The view commands: ``panorama``, ``cylinder``, ``plane``, ``perspective``, ``floor``."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import click
import numpy as np

from ..errors import PanomapError
from ..io.images import pgm_map_paths, read_image, save_map, save_map_pgm, write_image
from ..remap import INTERPOLATIONS, Remapper
from ..table.table import SAMPLINGS, load_table
from ..views.views import (
    Band,
    CylinderPanorama,
    FloorView,
    GenericPanorama,
    PerspectiveView,
    PlaneView,
    View,
    build_map,
)
from .options import FINITE, PATH, SIZE


def view_options(function: Callable[..., Any]) -> Callable[..., Any]:
    """Arguments and options every view command shares."""
    decorators = [
        click.argument("table", type=PATH),
        click.argument("image", type=PATH),
        click.option("-o", "--output", type=PATH, required=True, help="Output image (PNG, TIFF, JPEG...)."),
        click.option("--save-map", type=PATH, help="Also write the (H, W, 2) float32 (u, v) map as .npy."),
        click.option(
            "--save-map-pgm",
            type=click.Path(path_type=Path),
            metavar="PREFIX",
            help="Also write the map for ffmpeg's remap filter: PREFIX_x.pgm and PREFIX_y.pgm "
            "(16-bit, nearest pixel, 65535 where there is no source).",
        ),
        click.option(
            "--interp",
            type=click.Choice(list(INTERPOLATIONS)),
            default="linear",
            show_default=True,
            help="Image interpolation.",
        ),
        click.option(
            "--table-sampling",
            type=click.Choice(SAMPLINGS),
            default="bilinear",
            show_default=True,
            help="'nearest' uses the paper's floor indices.",
        ),
    ]
    for decorator in reversed(decorators):
        function = decorator(function)
    return function


def _render(
    table_path: Path,
    image_path: Path,
    output: Path,
    maps: tuple[Path | None, Path | None],
    interp: str,
    sampling: str,
    make_view: Callable[[], View],
) -> None:
    save_map_path, pgm_prefix = maps
    view = make_view()
    table = load_table(table_path)
    image = read_image(image_path)
    if table.image_size is not None and (image.shape[1], image.shape[0]) != table.image_size:
        raise PanomapError(
            f"the image is {image.shape[1]} x {image.shape[0]}, the table {table_path} is for "
            f"{table.image_size[0]} x {table.image_size[1]} images",
            image_path,
        )
    extra = [save_map_path] if save_map_path is not None else []
    if pgm_prefix is not None:
        extra += pgm_map_paths(pgm_prefix)
    for path in extra:
        if not (path.parent if str(path.parent) else Path(".")).is_dir():
            raise PanomapError("its folder does not exist", path)
    map_uv = build_map(table, view, sampling)
    remapper = Remapper(map_uv, (image.shape[1], image.shape[0]), interp)
    write_image(output, remapper(image))
    if save_map_path is not None:
        save_map(save_map_path, map_uv)
    if pgm_prefix is not None:
        save_map_pgm(pgm_prefix, map_uv)
    valid = float(np.mean(np.all(np.isfinite(map_uv), axis=2)))
    click.echo(
        f"wrote {output} ({map_uv.shape[1]} x {map_uv.shape[0]}, {valid:.0%} of pixels with a source)"
        + "".join(f" and {path}" for path in extra)
    )


@click.command()
@view_options
@click.option("--size", type=SIZE, help="Output WxH [default: the table's M x N].")
@click.option("--start-deg", type=FINITE, default=0.0, show_default=True, help="Azimuth at the left edge.")
def panorama(
    table: Path,
    image: Path,
    output: Path,
    save_map: Path | None,
    save_map_pgm: Path | None,
    interp: str,
    table_sampling: str,
    size: tuple[int, int] | None,
    start_deg: float,
) -> None:
    """Generic panorama (paper 2.3.1): columns are azimuths (decreasing to the right), rows elevations."""
    _render(
        table,
        image,
        output,
        (save_map, save_map_pgm),
        interp,
        table_sampling,
        lambda: GenericPanorama(size, math.radians(start_deg)),
    )


@click.command()
@view_options
@click.option("--distance", type=FINITE, required=True, help="Horizontal distance D of the cylinder.")
@click.option(
    "--band",
    nargs=2,
    type=FINITE,
    required=True,
    metavar="ZB ZT",
    help="Heights of the band's bottom and top relative to the camera.",
)
@click.option("--size", type=SIZE, required=True, help="Output WxH.")
@click.option("--start-deg", type=FINITE, default=0.0, show_default=True, help="Azimuth at the left edge.")
def cylinder(
    table: Path,
    image: Path,
    output: Path,
    save_map: Path | None,
    save_map_pgm: Path | None,
    interp: str,
    table_sampling: str,
    distance: float,
    band: tuple[float, float],
    size: tuple[int, int],
    start_deg: float,
) -> None:
    """Panorama of a cylinder at distance D with a height band (paper 2.3.2)."""
    _render(
        table,
        image,
        output,
        (save_map, save_map_pgm),
        interp,
        table_sampling,
        lambda: CylinderPanorama(distance, Band(*band), size, math.radians(start_deg)),
    )


@click.command()
@view_options
@click.option("--distance", type=FINITE, required=True, help="Horizontal distance D of both vertical edges.")
@click.option("--plane-width", type=FINITE, required=True, help="Plane width W_p (at most 2 D).")
@click.option(
    "--band",
    nargs=2,
    type=FINITE,
    required=True,
    metavar="ZB ZT",
    help="Heights of the plane's bottom and top relative to the camera.",
)
@click.option("--azimuth-deg", type=FINITE, required=True, help="Azimuth of the plane's centre.")
@click.option("--size", type=SIZE, required=True, help="Output WxH.")
def plane(
    table: Path,
    image: Path,
    output: Path,
    save_map: Path | None,
    save_map_pgm: Path | None,
    interp: str,
    table_sampling: str,
    distance: float,
    plane_width: float,
    band: tuple[float, float],
    azimuth_deg: float,
    size: tuple[int, int],
) -> None:
    """Perspective view of a vertical W_p x band plane at distance D (paper 2.3.3)."""
    _render(
        table,
        image,
        output,
        (save_map, save_map_pgm),
        interp,
        table_sampling,
        lambda: PlaneView(distance, plane_width, Band(*band), math.radians(azimuth_deg), size),
    )


@click.command()
@view_options
@click.option("--yaw-deg", type=FINITE, required=True, help="Azimuth of the optical axis (counter-clockwise from +X).")
@click.option(
    "--pitch-deg", type=FINITE, required=True, help="Elevation of the optical axis, -90..90 (negative looks down)."
)
@click.option(
    "--roll-deg", type=FINITE, default=0.0, show_default=True, help="Turn about the optical axis (+ dips the right)."
)
@click.option("--fov-deg", type=FINITE, required=True, help="Horizontal field of view, more than 0 and less than 180.")
@click.option("--size", type=SIZE, required=True, help="Output WxH.")
def perspective(
    table: Path,
    image: Path,
    output: Path,
    save_map: Path | None,
    save_map_pgm: Path | None,
    interp: str,
    table_sampling: str,
    yaw_deg: float,
    pitch_deg: float,
    roll_deg: float,
    fov_deg: float,
    size: tuple[int, int],
) -> None:
    """Virtual pan-tilt-zoom camera: a pinhole at the camera position looking anywhere."""
    _render(
        table,
        image,
        output,
        (save_map, save_map_pgm),
        interp,
        table_sampling,
        lambda: PerspectiveView(
            math.radians(yaw_deg), math.radians(pitch_deg), math.radians(roll_deg), math.radians(fov_deg), size
        ),
    )


@click.command()
@view_options
@click.option("--z", "z_plane", type=FINITE, required=True, help="Height Z of the plane (world).")
@click.option("--x", "x_range", nargs=2, type=FINITE, required=True, metavar="XMIN XMAX", help="World X extent.")
@click.option("--y", "y_range", nargs=2, type=FINITE, required=True, metavar="YMIN YMAX", help="World Y extent.")
@click.option("--size", type=SIZE, help="Output WxH (or give --resolution).")
@click.option("--resolution", type=FINITE, help="World units per pixel, instead of --size.")
def floor(
    table: Path,
    image: Path,
    output: Path,
    save_map: Path | None,
    save_map_pgm: Path | None,
    interp: str,
    table_sampling: str,
    z_plane: float,
    x_range: tuple[float, float],
    y_range: tuple[float, float],
    size: tuple[int, int] | None,
    resolution: float | None,
) -> None:
    """Bird's-eye map of the horizontal plane Z (world): +X to the right, +Y up."""
    if (size is None) == (resolution is None):
        raise click.UsageError("give the output size as --size WxH or --resolution R, one of the two")

    def make_view() -> FloorView:
        if size is not None:
            return FloorView(z_plane, x_range, y_range, size)
        assert resolution is not None
        return FloorView.with_resolution(z_plane, x_range, y_range, resolution)

    _render(table, image, output, (save_map, save_map_pgm), interp, table_sampling, make_view)
