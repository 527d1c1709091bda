"""The ``panomap`` command line: parses input, calls the library, reports.

Angles on the command line are in degrees; lengths in world units; sizes as
``WxH`` (views) or ``MxN`` (tables). Bad input gets one line on stderr,
naming the file and the problem, and a non-zero exit code (1 for bad input,
2 for bad usage); outputs are written to a temporary name and renamed when
complete.
"""

from __future__ import annotations

import csv
import io
import json
import math
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any, NoReturn

import click
import numpy as np

from . import __version__
from .centre import ImageCircles, draw_overlay, find_image_circles
from .errors import PanomapError
from .files import write_text_atomic
from .geometry import ray_plane_points
from .imageio import image_size, pgm_map_paths, read_image, save_map, save_map_pgm, write_image
from .landmarks import read_landmarks, read_points
from .pipeline import fit_table
from .radial import MODELS
from .remap import INTERPOLATIONS, Remapper
from .table import SAMPLINGS, PanoMappingTable, load_table
from .views import (
    Band,
    CylinderPanorama,
    FloorView,
    GenericPanorama,
    PerspectiveView,
    PlaneView,
    View,
    build_map,
)


class Size(click.ParamType):
    """``WxH`` (or ``MxN``): two integers joined by ``x``."""

    name = "WxH"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> tuple[int, int]:
        if isinstance(value, tuple):
            return value
        text = str(value).lower().replace("*", "x")
        parts = text.split("x")
        try:
            if len(parts) != 2:
                raise ValueError
            return int(parts[0]), int(parts[1])
        except ValueError:
            self.fail(f"{value!r} is not a size like 1024x512", param, ctx)


class Finite(click.ParamType):
    """A finite real number (refuses nan and inf)."""

    name = "NUMBER"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> float:
        try:
            number = float(value)
        except (TypeError, ValueError):
            self.fail(f"{value!r} is not a number", param, ctx)
        if not math.isfinite(number):
            self.fail(f"{value!r} is not a finite number", param, ctx)
        return number


SIZE = Size()
FINITE = Finite()
PATH = click.Path(path_type=Path, dir_okay=False)


def _fail(message: str, code: int = 1) -> NoReturn:
    click.echo(f"panomap: error: {message}", err=True)
    sys.exit(code)


class PanomapGroup(click.Group):
    """A group that reports every error in one line, without a traceback."""

    def main(self, *args: Any, **kwargs: Any) -> NoReturn:
        kwargs["standalone_mode"] = False
        try:
            result = super().main(*args, **kwargs)
        except click.UsageError as exc:
            where = exc.ctx.command_path if exc.ctx is not None else "panomap"
            message = " ".join(exc.format_message().split())
            click.echo(f"{where}: error: {message} (see '{where} --help')", err=True)
            sys.exit(exc.exit_code)
        except click.ClickException as exc:
            _fail(" ".join(exc.format_message().split()), exc.exit_code)
        except click.Abort:
            _fail("interrupted", 130)
        except PanomapError as exc:
            _fail(" ".join(str(exc).split()))
        except OSError as exc:
            _fail(f"{exc.filename or ''}: {exc.strerror or exc}".lstrip(": "))
        sys.exit(result if isinstance(result, int) else 0)


@click.group(cls=PanomapGroup, context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(__version__, prog_name="panomap")
def main() -> None:
    """Unwarp omni-images (mirror and fisheye cameras) with pano-mapping tables.

    \b
    1. panomap fit LANDMARKS.csv -o cam.npz --camera X0 Y0 Z0 --centre U0 V0
    2. panomap panorama cam.npz omni.png -o pano.png
       panomap cylinder cam.npz omni.png -o cyl.png --distance 2 --band -2.4 0 --size 2048x512
       panomap plane    cam.npz omni.png -o view.png --distance 2 --plane-width 2 \\
                        --band -2.4 0 --azimuth-deg 30 --size 800x800
       panomap perspective cam.npz omni.png -o ptz.png --yaw-deg 270 --pitch-deg -30 \\
                        --fov-deg 100 --size 1280x720
       panomap floor    cam.npz omni.png -o floor.png --z 0 --x 0 6 --y 0 5 --resolution 0.01
       panomap unproject cam.npz pixels.csv -o rays.csv --z 0
    3. panomap demo   (renders a simulated room and does all of it)

    Conventions: world Z up; azimuth counter-clockwise from +X seen from above;
    elevation negative below the camera; pixel (u, v) = (column, row) with the
    centre of the top-left pixel at (0, 0). See docs/conventions.md.
    """


# ----------------------------------------------------------------------------- fit


@main.command()
@click.argument("landmarks", type=PATH)
@click.option("-o", "--output", type=PATH, required=True, help="Table file to write (.npz).")
@click.option(
    "--camera",
    nargs=3,
    type=FINITE,
    metavar="X0 Y0 Z0",
    help="Camera (mirror centre) position in world units; or give it in a JSON landmark file.",
)
@click.option(
    "--centre",
    "--center",
    "centre",
    nargs=2,
    type=FINITE,
    metavar="U0 V0",
    help="Image centre (px) where the optical axis lands.",
)
@click.option(
    "--image",
    type=PATH,
    help="An omni-image of this camera: gives the image size, and the centre and radii when they are not given.",
)
@click.option("--image-size", type=SIZE, help="Image size WxH when no --image is given.")
@click.option(
    "--size",
    "table_size",
    type=SIZE,
    metavar="MxN",
    help="Table size: M azimuths x N elevations [default: about 1 entry per pixel].",
)
@click.option(
    "--cutoff-radius", type=FINITE, help="Radius (px) of the self-occlusion disc [default: found in --image, else 0]."
)
@click.option(
    "--outer-radius",
    type=FINITE,
    help="Radius (px) of the image circle [default: found in --image, else the largest circle in the image].",
)
@click.option(
    "--model",
    type=click.Choice(["auto", *MODELS]),
    default="auto",
    show_default=True,
    help="Radial model; 'paper' is the paper's 4th-degree polynomial, 'auto' chooses by leave-one-out.",
)
@click.option(
    "--azimuth",
    type=click.Choice(["fit", "paper"]),
    default="fit",
    show_default=True,
    help="Estimate the image rotation phi0 and mirroring s, or assume the paper's s=+1, phi0=0.",
)
@click.option(
    "--axis", type=click.Choice(["down", "up"]), help="Force the viewing direction [default: from the landmarks]."
)
@click.option(
    "--refine-centre",
    is_flag=True,
    help="Refine the centre together with the radial function and phi0 (advised when the centre is found in "
    "--image: on a real mirror the rim's centre can be pixels from the optical axis).",
)
@click.option(
    "--pixel-sigma",
    type=FINITE,
    default=1.0,
    show_default=True,
    help="Standard deviation of the landmarks' pixels (px), for weighting.",
)
@click.option(
    "--world-sigma",
    type=FINITE,
    help="Standard deviation of the landmarks' world coordinates (world units) [default: 0.4% of their "
    "median distance].",
)
@click.option("--keep-outliers", is_flag=True, help="Keep landmarks that disagree with the rest (default: drop them).")
@click.option("--plot", type=PATH, help="Also write the fit plot (PNG): the curve, landmarks and residuals.")
def fit(
    landmarks: Path,
    output: Path,
    camera: tuple[float, float, float] | None,
    centre: tuple[float, float] | None,
    image: Path | None,
    image_size: tuple[int, int] | None,
    table_size: tuple[int, int] | None,
    cutoff_radius: float | None,
    outer_radius: float | None,
    model: str,
    azimuth: str,
    axis: str | None,
    refine_centre: bool,
    pixel_sigma: float,
    world_sigma: float | None,
    keep_outliers: bool,
    plot: Path | None,
) -> None:
    """Fit the camera to LANDMARKS (CSV u,v,X,Y,Z[,name] or JSON) and write its pano-mapping table."""
    pairs = read_landmarks(landmarks)
    position = camera or pairs.camera
    if position is None:
        raise PanomapError('no camera position: give --camera X0 Y0 Z0 or "camera" in the JSON', landmarks)
    info: dict[str, Any] = {}
    sources = {"camera_position": "given" if camera else "landmark file"}
    sources |= {
        name: "given"
        for name, value in (("centre", centre), ("cutoff_radius", cutoff_radius), ("outer_radius", outer_radius))
        if value is not None
    }
    size = _image_size(None, image_size)
    if image is not None:
        omni = read_image(image)
        size = (int(omni.shape[1]), int(omni.shape[0]))
        if centre is None or cutoff_radius is None or outer_radius is None:
            try:
                circles = find_image_circles_in(image, omni)
            except PanomapError as exc:
                if centre is None:
                    raise
                # The centre is given: only the radii were wanted; keep their defaults and say so.
                click.echo(f"panomap: warning: {exc}; using the default radii", err=True)
                circles = None
        else:
            circles = None
        if circles is not None:
            info["image_circles"] = circles.to_dict()
            if centre is None:
                centre, sources["centre"] = circles.centre, "detected"
            if outer_radius is None:
                outer_radius, sources["outer_radius"] = circles.outer_radius, "detected"
            if cutoff_radius is None:
                cutoff_radius = circles.cutoff_radius or 0.0
                sources["cutoff_radius"] = "detected" if circles.cutoff else "detected: none (no self-occlusion disc)"
    if centre is None:
        raise PanomapError("no image centre: give --centre U0 V0, or --image OMNI to find it", landmarks)
    info["sources"] = sources
    if refine_centre:
        sources["centre"] = f"{sources['centre']}, refined with the landmarks"
    try:
        table = fit_table(
            pairs,
            position,
            centre,
            image_size=size,
            cutoff_radius=cutoff_radius,
            outer_radius=outer_radius,
            table_size=table_size,
            model=model,
            azimuth=azimuth,
            axis=axis,
            refine_centre=refine_centre,
            pixel_sigma=pixel_sigma,
            world_sigma=world_sigma,
            reject_outliers=not keep_outliers,
            info=info,
        )
    except PanomapError as exc:
        raise PanomapError(exc.detail, exc.source or landmarks) from None
    table.save(output)
    if plot is not None:
        from .plot import save_fit_plot

        save_fit_plot(table, plot)
    click.echo(_describe_fit(table))
    click.echo(f"wrote {output}" + (f" and {plot}" if plot else ""))
    for warning in table.info.get("warnings", []):
        click.echo(f"panomap: warning: {warning}", err=True)


@main.command()
@click.argument("image", type=PATH)
@click.option("--json", "as_json", is_flag=True, help="Print the result as JSON.")
@click.option("--overlay", type=PATH, help="Also write the image with the circles drawn on it (PNG).")
def centre(image: Path, as_json: bool, overlay: Path | None) -> None:
    """Find the image centre, the cut-off radius and the image circle of an omni-image.

    The centre is the rim's centre to a fraction of a pixel (the ellipse's, when the
    rim is one); the cut-off radius is "none" for a camera that does not see itself
    (a fisheye). Fails with a reason, never a guess, when there is no image circle.
    """
    omni = read_image(image)
    circles = find_image_circles_in(image, omni)
    if overlay is not None:
        write_image(overlay, draw_overlay(omni, circles))
    if as_json:
        click.echo(json.dumps(circles.to_dict(), indent=2))
        return
    u0, v0 = circles.centre
    cutoff = "none" if circles.cutoff is None else f"{circles.cutoff.radius:.2f} px"
    click.echo(f"centre: {u0:.2f} {v0:.2f}")
    click.echo(f"cut-off radius: {cutoff}")
    click.echo(
        f"outer radius: {circles.outer.radius:.2f} px (fit RMS {circles.outer.rms_px:.2f} px, "
        f"{circles.outer.inliers} of {circles.outer.rays} rays)"
    )
    if circles.ellipse is not None:
        e = circles.ellipse
        click.echo(
            f"the rim is an ellipse: semi-axes {e.semi_axes[0]:.2f} and {e.semi_axes[1]:.2f} px, "
            f"angle {e.angle_deg:.1f} deg"
        )
    if overlay is not None:
        click.echo(f"wrote {overlay}")


def find_image_circles_in(path: Path, image: Any) -> ImageCircles:
    """Find the image circles, naming the file in any error."""
    try:
        return find_image_circles(image)
    except PanomapError as exc:
        raise PanomapError(exc.detail, path) from None


def _image_size(image: Path | None, size: tuple[int, int] | None) -> tuple[int, int] | None:
    if image is not None:
        return image_size(image)
    if size is not None:
        width, height = size
        if width <= 0 or height <= 0:
            raise PanomapError(f"--image-size {width}x{height}: must be positive")
        return size
    return None


def _describe_fit(table: PanoMappingTable) -> str:
    fit = table.info.get("fit", {})
    lines = []
    selection = fit.get("model_selection_loo_rms_px") or {}
    chosen = fit.get("model")
    if selection:
        ranked = ", ".join(
            f"{k} {v:.3f}" if v is not None else f"{k} -"
            for k, v in sorted(selection.items(), key=lambda kv: (kv[1] is None, kv[1] or 0))
        )
        lines.append(f"radial model: {chosen} (leave-one-out RMS px: {ranked})")
    else:
        lines.append(f"radial model: {chosen} (forced)")
    mirrored = "mirrored" if fit.get("s") == -1 else "not mirrored"
    lines.append(
        f"camera looks {fit.get('axis')} ({fit.get('axis_source')}); azimuth mapping phi = "
        f"{'-' if fit.get('s') == -1 else ''}theta {fit.get('phi0_deg', 0.0):+.2f} deg "
        f"({mirrored}, {'fitted' if fit.get('azimuth_mode') == 'fit' else 'assumed as in the paper'}; "
        f"consistency {fit.get('azimuth_consistency', float('nan')):.3f})"
    )
    lines.append(f"{'landmark':<12} {'u':>9} {'v':>9} {'elev deg':>9} {'azim deg':>9} {'resid px':>9}")
    for row in fit.get("landmarks", []):
        lines.append(
            f"{row['name'][:12]:<12} {row['u']:9.2f} {row['v']:9.2f} {row['elevation_deg']:9.2f} "
            f"{row['azimuth_deg']:9.2f} {row['residual_px']:9.3f}"
            + ("  OUTLIER (not used)" if row.get("outlier") else "")
        )
    if fit.get("outliers"):
        lines.append(f"outliers dropped: {', '.join(fit['outliers'])}")
    lines.append(
        f"residuals: RMS {fit.get('rms_px', float('nan')):.3f} px, max {fit.get('max_px', float('nan')):.3f} px"
    )
    uncertainty = fit.get("uncertainty") or {}
    if uncertainty:
        inside = uncertainty.get("max_se_in_landmark_range_px")
        lines.append(
            "radius standard error: up to "
            + (f"{inside:.2f} px within the landmarks' elevations, " if inside is not None else "")
            + f"up to {uncertainty['max_se_px']:.2f} px over the table's range"
        )
    lines.append(_describe_table(table))
    return "\n".join(lines)


def _describe_table(table: PanoMappingTable) -> str:
    m, n = table.size
    rho_s, rho_e = (math.degrees(x) for x in table.elevation_range)
    sources = table.info.get("sources", {})
    return (
        f"table: {m} x {n} entries, elevation {rho_s:.2f}..{rho_e:.2f} deg, "
        f"cut-off radius {table.cutoff_radius:.1f} px ({sources.get('cutoff_radius', '?')}), "
        f"outer radius {table.outer_radius:.1f} px ({sources.get('outer_radius', '?')})"
    )


# ----------------------------------------------------------------------------- info


@main.command()
@click.argument("table", type=PATH)
@click.option("--json", "as_json", is_flag=True, help="Print the metadata as JSON.")
def info(table: Path, as_json: bool) -> None:
    """Print a table's metadata: model, centre, s, phi0, range, sizes, landmarks and residuals."""
    loaded = load_table(table)
    meta = loaded.metadata()
    if as_json:
        click.echo(json.dumps(meta, indent=2))
        return
    model = loaded.model
    size = "unknown" if loaded.image_size is None else f"{loaded.image_size[0]} x {loaded.image_size[1]}"
    lines = [
        f"{table}: panomap table, format version {meta['version']}",
        f"image size: {size}; centre (u0, v0) = ({model.centre[0]:.3f}, {model.centre[1]:.3f}) "
        f"({loaded.info.get('sources', {}).get('centre', '?')})",
        f"camera position (X0, Y0, Z0) = {tuple(round(c, 6) for c in loaded.camera_position)}",
        f"radial model: {model.radial.kind}, axis {model.radial.axis}, coefficients "
        + ", ".join(f"{c:.9g}" for c in model.radial.coefficients),
        f"azimuth mapping: s = {model.s:+d}, phi0 = {math.degrees(model.phi0):.4f} deg",
    ]
    text = _describe_fit(loaded).splitlines()
    click.echo("\n".join(lines + text[2:]))


# ----------------------------------------------------------------------------- views


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


@main.command()
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


@main.command()
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


@main.command()
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


@main.command()
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


@main.command()
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


# ----------------------------------------------------------------------------- project


@main.command()
@click.argument("table", type=PATH)
@click.argument("points", type=PATH)
@click.option("-o", "--output", type=PATH, required=True, help="CSV to write: the input columns plus u,v.")
@click.option("--table-sampling", type=click.Choice(SAMPLINGS), default="bilinear", show_default=True)
def project(table: Path, points: Path, output: Path, table_sampling: str) -> None:
    """World points (CSV with X,Y,Z) to pixels through the table; u,v empty where not visible."""
    loaded = load_table(table)
    header, rows, xyz = read_points(points)
    uv = loaded.project(xyz, table_sampling)
    keep = [i for i, name in enumerate(header) if name.lower() not in ("u", "v")]
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow([header[i] for i in keep] + ["u", "v"])
    for row, (u, v) in zip(rows, uv.tolist(), strict=True):
        pixel = ["", ""] if not (math.isfinite(u) and math.isfinite(v)) else [f"{u:.4f}", f"{v:.4f}"]
        writer.writerow([row[i] for i in keep] + pixel)
    write_text_atomic(output, buffer.getvalue())
    visible = int(np.count_nonzero(np.all(np.isfinite(uv), axis=1)))
    click.echo(f"wrote {output} ({visible} of {len(rows)} points visible)")


# ----------------------------------------------------------------------------- unproject


@main.command()
@click.argument("table", type=PATH)
@click.argument("pixels", type=PATH)
@click.option(
    "-o", "--output", type=PATH, required=True, help="CSV to write: the input columns plus azimuth_deg,elevation_deg."
)
@click.option(
    "--z", "z_plane", type=FINITE, help="Also give X,Y,Z where each pixel's ray meets the horizontal plane Z (world)."
)
def unproject(table: Path, pixels: Path, output: Path, z_plane: float | None) -> None:
    """Pixels (CSV with u,v) to rays: azimuth and elevation, empty outside the valid region."""
    loaded = load_table(table)
    header, rows, uv = read_points(pixels, ("u", "v"))
    theta, rho = loaded.unproject(uv)
    added = ["azimuth_deg", "elevation_deg"] + (["X", "Y", "Z"] if z_plane is not None else [])
    replaced = {name.lower() for name in added}
    keep = [i for i, name in enumerate(header) if name.lower() not in replaced]
    world = (
        ray_plane_points(loaded.camera_position, theta, rho, z_plane)
        if z_plane is not None
        else np.full((len(rows), 0), np.nan)
    )
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow([header[i] for i in keep] + added)
    for row, azimuth, elevation, point in zip(rows, theta.tolist(), rho.tolist(), world.tolist(), strict=True):
        seen = math.isfinite(elevation)
        ray = [f"{math.degrees(azimuth):.6f}", f"{math.degrees(elevation):.6f}"] if seen else ["", ""]
        where = ["" if not math.isfinite(c) else f"{c:.6f}" for c in point]
        writer.writerow([row[i] for i in keep] + ray + where)
    write_text_atomic(output, buffer.getvalue())
    valid = int(np.count_nonzero(np.isfinite(rho)))
    message = f"wrote {output} ({valid} of {len(rows)} pixels in the valid region"
    if z_plane is not None:
        reached = int(np.count_nonzero(np.all(np.isfinite(world), axis=1)))
        message += f"; {reached} rays reach the plane Z = {z_plane:g}"
    click.echo(message + ")")


# ----------------------------------------------------------------------------- demo


@main.command()
@click.option(
    "--out",
    type=click.Path(path_type=Path, file_okay=False),
    default=Path("demo-out"),
    show_default=True,
    help="Folder for everything the demo writes.",
)
@click.option(
    "--camera",
    "camera_name",
    type=click.Choice(["equidistant", "equisolid", "parabolic", "hyperbolic", "spherical"]),
    default="hyperbolic",
    show_default=True,
    help="Simulated ceiling camera to use.",
)
def demo(out: Path, camera_name: str) -> None:
    """Render the bundled room through a simulated ceiling camera, learn it, and unwarp it."""
    from .demo import run_demo

    for line in run_demo(out, camera_name):
        click.echo(line)


def _add_commands() -> None:
    """Commands that live in modules of their own (they import this module's types)."""
    from .cli_video import video
    from .learn.cli import learn

    main.add_command(video)
    main.add_command(learn)


_add_commands()
