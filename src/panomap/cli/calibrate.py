"""``panomap fit``, ``centre`` and ``info``: from landmarks to a table, and what a table holds."""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import click
from click.core import ParameterSource

from ..calibrate.circles import ImageCircles, NoImageCircle, find_image_circles
from ..calibrate.circles.side_by_side import side_by_side_half
from ..calibrate.core.report import FitReport, table_fit_report
from ..calibrate.core.sources import Source
from ..calibrate.landmarks.diagnosis import diagnose
from ..calibrate.landmarks.pairs import Landmarks, read_landmarks
from ..calibrate.landmarks.pipeline import calibrate_camera
from ..calibrate.landmarks.viewpoint import VIEWPOINT_MODES, SphericalMirror
from ..camera.image_terms import check_term_names
from ..camera.model import CameraModel
from ..camera.radial_models import MODELS
from ..errors import PanomapError, printable
from ..files import all_or_none, check_outputs, input_file
from ..io.images import header_size, write_image
from ..io.overlay import draw_no_rim_overlay, draw_overlay
from ..table.file import load_table, save_table
from ..table.table import PanoMappingTable
from .fit_checks import (
    check_landmark_fit_options,
    check_mount_options,
    check_table_room,
    expand_images,
    refuse_landmark_options,
    refuse_picture_as_landmarks,
)
from .options import (
    FINITE,
    NON_NEGATIVE,
    PATH,
    POSITIVE,
    SIZE,
    TILT,
    check_radii,
    check_table_outputs,
    frame_time_option,
    orientation_option,
    progress_bar,
    quiet,
    read_omni,
    refuse_same_input,
    say,
    say_note,
    warn_orientation,
    with_option_names,
)
from .progress import ProgressBar


@click.command()
@click.argument("landmarks", type=PATH, required=False)
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
    "images",
    type=click.Path(path_type=str),
    multiple=True,
    metavar="FILE|FOLDER|'GLOB'",
    help="An omni-image (or video) of this camera: gives the image size, and the centre and radii when they are "
    "not given. Without LANDMARKS the camera is learned from the straight lines in it; repeat --image, or give "
    "a folder (every picture in it) or a quoted glob ('shots/*.jpg'), to pool several pictures of the camera.",
)
@click.option(
    "--video",
    "videos",
    type=PATH,
    multiple=True,
    help="Learning from lines: a video of this camera; --video-frames frames taken apart in time pool their lines "
    "(a robot's camera that moves sees new edges in each; a fixed camera's frames that show one view count once).",
)
@click.option(
    "--video-frames",
    type=click.IntRange(1, 64),
    default=8,
    show_default=True,
    help="Learning from lines: how many frames of each --video, evenly spread over it.",
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
    "--cutoff-radius",
    type=NON_NEGATIVE,
    help="Radius (px) of the self-occlusion disc [default: found in --image, else 0].",
)
@click.option(
    "--outer-radius",
    type=POSITIVE,
    help="Radius (px) of the image circle [default: found in --image (the whole frame where it shows no rim), "
    "else the largest circle in the image].",
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
    "--refine-centre/--no-refine-centre",
    default=None,
    help="Refine the centre together with the radial function and phi0 [default: refined when the centre is "
    "found in --image (on a real mirror the rim's centre can be pixels from the optical axis), kept when --centre "
    "gives it].",
)
@click.option(
    "--pixel-sigma",
    type=POSITIVE,
    default=1.0,
    show_default=True,
    help="Standard deviation of the landmarks' pixels (px), for weighting.",
)
@click.option(
    "--world-sigma",
    type=NON_NEGATIVE,
    help="Standard deviation of the landmarks' world coordinates (world units) [default: 0.4% of their "
    "median distance].",
)
@orientation_option(
    "A camera looking any way (deg, as a perspective view's: pitch 0 ahead, -90 straight down): the fit starts "
    "from it and --tilt fit refines its axis from there. Replaces --axis and a --tilt pair. (Learning from "
    "pictures finds no world direction: turn its table with panomap orient.)"
)
@click.option(
    "--tilt",
    "tilt",
    type=TILT,
    default="fit",
    show_default=True,
    metavar="fit|none|'DEG AZ_DEG'",
    help="The camera's axis off the vertical: 'fit' estimates it and keeps it when cross-validation says the "
    "landmarks support it; 'none' takes the camera as level (the paper); 'DEG AZ_DEG' (one argument, quoted) fixes "
    "it: the optical axis DEG off the vertical, leaning toward world azimuth AZ_DEG.",
)
@click.option(
    "--camera-sigma",
    type=NON_NEGATIVE,
    help="Standard deviation of each coordinate of --camera (world units: a tape measurement); the fit refines "
    "the position when cross-validation says the landmarks support it; 0 keeps it exact [default: 1% of the "
    "landmarks' median distance].",
)
@click.option(
    "--viewpoint",
    type=click.Choice(VIEWPOINT_MODES),
    default="auto",
    show_default=True,
    help="A mirror without a single viewpoint (a sphere, a cone): 'auto' gives a mirror camera (a cut-off disc "
    "shows) each elevation's ray origin on its axis where cross-validation over the landmarks chooses it; "
    "'single' keeps every ray from --camera (the paper); 'caustic' fits the ray origins whatever "
    "cross-validation says (a mirror known to be a sphere or a cone).",
)
@click.option(
    "--sphere-radius",
    type=POSITIVE,
    metavar="R",
    help="The mirror is a sphere of this radius (world units, as the landmarks'): its own law and the ray "
    "origins it gives are fitted (a dozen landmarks at room distances pin the sphere's size only within about "
    "its own size; a ruler pins it).",
)
@click.option(
    "--lines/--no-lines",
    "use_lines",
    default=True,
    show_default=True,
    help="With LANDMARKS and --image: the straight lines of the image join the landmarks in the fit, each "
    "weighted by its measured noise (they fix the radial function and the centre; the landmarks the azimuth, "
    "the tilt and the position).",
)
@click.option(
    "--boards/--no-boards",
    "use_boards",
    default=True,
    show_default=True,
    help="Learning from lines: checkerboards in the images (any size, found by their corners) come first; their "
    "evenly spaced rows and columns fix the scale that straightness alone leaves loose. --no-boards fits the "
    "images' edges only.",
)
@click.option("--keep-outliers", is_flag=True, help="Keep landmarks that disagree with the rest (default: drop them).")
@click.option("--plot", type=PATH, help="Also write the fit plot (PNG): the curve, landmarks and residuals.")
@click.option(
    "--overlay",
    type=PATH,
    help="Also write --image with the fit drawn on it (PNG): the annulus and centre, circles of equal world "
    "elevation (the horizon cyan), azimuth 0, and each landmark's residual (outliers red).",
)
@click.option(
    "--uncertainty-plot",
    type=PATH,
    help="Learning from checkerboards: also write the projection uncertainty figure (PNG): each pixel's 95% band "
    "under the corners' noise, ring by ring (panomap info --uncertainty-plot draws it from the table).",
)
@click.option(
    "--azimuth-zero",
    nargs=2,
    type=FINITE,
    metavar="U V",
    help="Learning from lines: the pixel whose world azimuth is 0 [default: image angle 0, the +u direction].",
)
@click.option(
    "--handedness",
    type=click.Choice(["auto", "+1", "-1"]),
    default="auto",
    show_default=True,
    help="Learning from lines: s of the camera model (-1: the image is mirrored); 'auto': +1 for a mirror camera "
    "(a cut-off disc shows), -1 for a lens, looking down (the opposite looking up).",
)
@click.option(
    "--terms",
    default="auto",
    show_default=True,
    callback=lambda _ctx, _param, value: _checked_terms(value),
    help="Learning from checkerboards: the image terms beyond the radial law the camera may keep (aspect, skew, "
    "decentering, field, smooth): 'auto' keeps each only where the images left out say it helps, 'none', or names "
    "joined by commas (kept as given).",
)
@click.option(
    "--camera-height",
    type=POSITIVE,
    help="Learning from lines: the camera's height above the floor (world units); floor, cylinder and plane "
    "views need it, lines know no distance.",
)
@click.option(
    "-v",
    "--verbose",
    is_flag=True,
    help="Where the fit is refused: the figures behind the refusal (its bands, rings, folds) after its line.",
)
@frame_time_option
@with_option_names
def fit(
    landmarks: Path | None,
    output: Path,
    camera: tuple[float, float, float] | None,
    centre: tuple[float, float] | None,
    images: Any,
    videos: tuple[Path, ...],
    video_frames: int,
    image_size: tuple[int, int] | None,
    table_size: tuple[int, int] | None,
    cutoff_radius: float | None,
    outer_radius: float | None,
    model: str,
    azimuth: str,
    axis: str | None,
    refine_centre: bool | None,
    pixel_sigma: float,
    world_sigma: float | None,
    orientation: tuple[float, float, float] | None,
    tilt: str | tuple[float, float],
    camera_sigma: float | None,
    viewpoint: str,
    sphere_radius: float | None,
    use_lines: bool,
    use_boards: bool,
    keep_outliers: bool,
    plot: Path | None,
    overlay: Path | None,
    uncertainty_plot: Path | None,
    azimuth_zero: tuple[float, float] | None,
    handedness: str,
    terms: str,
    camera_height: float | None,
    frame_time: float | None,
) -> None:
    """Make the camera's table: learned from pictures (--image), or fitted to LANDMARKS (CSV u,v,X,Y,Z or JSON).

    With LANDMARKS, fit the camera to them and write its pano-mapping table. Without LANDMARKS, learn the
    camera from the straight lines in --image (walls, door and window frames,
    shelves, floor tiles; a checkerboard of any size first, where one shows): no measurement needed. Lines
    know neither the azimuth origin (--azimuth-zero), the handedness (--handedness) nor any distance (--camera-height).
    """
    # Options missing or out of range are usage errors (exit 2); the files' problems are failures (1).
    refuse_picture_as_landmarks(landmarks)
    images = expand_images(images)
    if not videos and click.get_current_context().get_parameter_source("video_frames") is ParameterSource.COMMANDLINE:
        raise click.UsageError("--video-frames is how many frames of --video to take: give --video FILE too")
    if landmarks is None:
        if not use_lines:
            raise click.UsageError("--no-lines leaves nothing to learn from without LANDMARKS")
        refuse_landmark_options(click.get_current_context())
        _fit_lines(
            output, images, overlay, plot, model, axis, azimuth_zero, handedness, camera_height, frame_time, use_boards,
            videos, video_frames, terms, uncertainty_plot,
        )  # fmt: skip
        return
    if videos:
        raise click.UsageError("--video pools frames to learn from lines (no LANDMARKS); a landmark fit takes --image "
                               "VIDEO --frame-time SECONDS")  # fmt: skip
    size = _image_size(image_size)
    check_radii(cutoff_radius, outer_radius)
    image = check_landmark_fit_options(
        landmarks, output, images, centre, table_size, model, refine_centre, plot, overlay,
        azimuth_zero, handedness, camera_height, terms, uncertainty_plot, size,
    )  # fmt: skip
    pairs = read_landmarks(landmarks)
    _check_camera_position(camera, pairs, landmarks)
    if frame_time is not None and image is None:
        raise click.UsageError("--frame-time picks a frame of --image: give --image VIDEO too")
    mirror = check_mount_options(model, azimuth, axis, tilt, orientation, viewpoint, sphere_radius)
    omni = None if image is None else read_omni(image, frame_time)
    if omni is not None and use_lines and mirror is not None:
        say_note(f"the image's lines do not join {mirror}: the landmarks alone fit it")
    if image is not None:
        warn_orientation(image)
    if omni is not None and size is not None and size != (omni.shape[1], omni.shape[0]):
        raise click.BadParameter(
            f"{size[0]}x{size[1]}, but {image} is {omni.shape[1]} x {omni.shape[0]} (give one of them)",
            param_hint="'--image-size'",
        )
    bar = progress_bar()
    joined = use_lines and omni is not None and mirror is None
    bar.stage(f"fitting the camera to {len(pairs.pixels)} landmarks" + (" and the image's lines" if joined else ""))
    try:
        result = calibrate_camera(
            pairs,
            camera,
            centre=centre,
            cutoff_radius=cutoff_radius,
            outer_radius=outer_radius,
            omni=omni,
            omni_name=image,
            image_size=size,
            table_size=table_size,
            model=model,
            azimuth=azimuth,
            axis=axis,
            refine_centre=refine_centre,
            pixel_sigma=pixel_sigma,
            world_sigma=world_sigma,
            reject_outliers=not keep_outliers,
            tilt_deg=tilt,
            camera_sigma=camera_sigma,
            lines=joined,
            viewpoint=viewpoint if sphere_radius is None else SphericalMirror(sphere_radius),
            orientation_deg=orientation,
        )
    except PanomapError as exc:
        bar.close()
        raise PanomapError(exc.detail, exc.source or landmarks) from None
    for warning in result.warnings:
        bar.write(f"panomap: warning: {warning}")
    for note in result.notes if not quiet() else ():
        bar.write(f"panomap: note: {note}")
    table = result.table
    _write_fit(table, result, output, plot, overlay, omni, bar)
    for warning in table.info.get("warnings", []):
        click.echo(f"panomap: warning: {warning}", err=True)


def _write_fit(
    table: PanoMappingTable,
    result: Any,
    output: Path,
    plot: Path | None,
    overlay: Path | None,
    omni: Any,
    bar: ProgressBar,
) -> None:
    """Write the table and its pictures (all or none), then say what the fit found and what was written."""
    bar.stage("writing the table" + (" and its pictures" if plot is not None or overlay is not None else ""))
    try:
        with all_or_none():
            save_table(table, output)
            if plot is not None:
                from ..io.plot import save_fit_plot

                save_fit_plot(table, plot)
            if overlay is not None and omni is not None:
                from ..io.overlay import draw_fit_overlay

                write_image(overlay, draw_fit_overlay(omni, table))
    finally:
        bar.close()
    say(printable(_describe_fit(table), keep="\n"))
    for note in diagnose(result.fit, centre_guessed=result.sources["centre"].source is Source.FRAME_CENTRE):
        click.echo(printable(f"diagnosis: {note}"), err=True)
    written = [str(path) for path in (output, plot, overlay) if path is not None]
    say("wrote " + (", ".join(written[:-1]) + " and " + written[-1] if len(written) > 1 else written[0]))


def _check_camera_position(camera: tuple[float, float, float] | None, pairs: Landmarks, landmarks: Path) -> None:
    """``--camera`` against the landmark file's own camera: one of them needed; ``--camera`` wins, with a warning
    where they differ."""
    if camera is None and pairs.camera is None:
        raise click.UsageError(
            f'no camera position in {landmarks}: give --camera X0 Y0 Z0 (or "camera" in a JSON landmark file)'
        )
    if camera is not None and pairs.camera is not None and tuple(camera) != tuple(pairs.camera):
        given, filed = (", ".join(f"{c:g}" for c in p) for p in (camera, pairs.camera))
        click.echo(f"panomap: warning: --camera ({given}) is used, not the camera in {landmarks} ({filed})", err=True)


def _fit_lines(
    output: Path,
    images: tuple[Path, ...],
    overlay: Path | None,
    plot: Path | None,
    model: str,
    axis: str | None,
    azimuth_zero: tuple[float, float] | None,
    handedness: str,
    camera_height: float | None,
    frame_time: float | None,
    use_boards: bool,
    videos: tuple[Path, ...] = (),
    video_frames: int = 8,
    terms: str = "auto",
    uncertainty_plot: Path | None = None,
) -> None:
    """``fit`` without landmarks: the camera learned from the lines (and checkerboards) of ``images`` and the
    frames of ``videos``."""
    from ..calibrate.lines.fit import LineFitOptions
    from .lines import fit_from_lines

    if not images and not videos:
        raise click.UsageError("give LANDMARKS, or --image OMNI to learn the camera from its straight lines")
    if frame_time is not None and not images:
        raise click.UsageError(
            "--frame-time picks a frame of --image VIDEO; --video takes its frames apart in time (--video-frames)"
        )
    if plot is not None:
        raise click.UsageError("--plot draws landmarks; learning from lines draws with --overlay")
    if model == "paper":
        raise click.UsageError("the paper model takes the centre as given; learning from lines needs another model")
    for path in (*images, *videos):
        input_file(path)  # (before the memory check reads their headers: a FIFO would block it)
    refuse_same_input(
        (*images, *videos),
        "picture",
        "its lines twice add nothing",
        lambda second: "'--image'" if second in images else "'--video'",
    )
    check_table_outputs(
        [*(("the image", path) for path in images), *(("the video", path) for path in videos)],
        output,
        pictures=[("--overlay", overlay, "the overlay"), ("--uncertainty-plot", uncertainty_plot, "the figure")],
    )
    check_table_room(output, None, header_size(images[0]) if images else None)
    options = LineFitOptions(
        axis=axis or "down",
        s=None if handedness == "auto" else int(handedness),
        azimuth_zero=azimuth_zero,
        model=model,
        terms=terms,
    )
    fit_from_lines(
        images,
        output,
        frame_time=frame_time,
        options=options,
        camera_height=camera_height,
        overlay=overlay,
        use_boards=use_boards,
        videos=videos,
        video_frames=video_frames,
        uncertainty_plot=uncertainty_plot,
    )


@click.command()
@click.argument("image", type=PATH)
@click.option("--json", "as_json", is_flag=True, help="Print the result as JSON.")
@click.option("--overlay", type=PATH, help="Also write the image with the circles drawn on it (PNG).")
@click.option(
    "-v",
    "--verbose",
    is_flag=True,
    help="Where no image circle is found: what the search found instead (how many rays crossed a rim), after its line.",
)
@frame_time_option
def centre(image: Path, as_json: bool, overlay: Path | None, frame_time: float | None, verbose: bool) -> None:
    """Find the image centre, the cut-off radius and the image circle of an omni-image.

    The centre is the rim's centre to a fraction of a pixel (the ellipse's, when the
    rim is one), fitted to the arcs of the rim that are visible when the frame cuts
    the circle; the cut-off radius is "none" for a camera that does not see itself
    (a fisheye). Fails with a reason, never a guess, when no rim is visible (a
    full-frame fisheye: the message gives the frame centre as a starting value; a
    mirror image that overfills the frame: the cut-off disc found and its centre) in
    one line; --verbose adds what the search found instead. The overlay then shows
    that disc and the starting value.
    """
    check_outputs([("the input image", image)], [("--overlay", overlay)])
    omni = read_omni(image, frame_time)
    warn_orientation(image)
    try:
        circles = find_image_circles(omni)
    except NoImageCircle as exc:
        if overlay is not None:
            write_image(overlay, draw_no_rim_overlay(omni, exc))
            say(f"wrote {overlay}")
        error = PanomapError(f"{exc.detail}\n{exc.reason}" if exc.reason else exc.detail, image)
        error.verbose = True if verbose else None  # type: ignore[attr-defined]  # (the figures with --verbose)
        raise error from None
    except PanomapError as exc:
        raise PanomapError(exc.detail, image) from None
    if overlay is not None:
        write_image(overlay, draw_overlay(omni, circles))
    if as_json:
        click.echo(json.dumps(circles.to_dict(), indent=2))
        return
    u0, v0 = circles.centre
    cutoff = "none"
    if circles.cutoff is not None:  # its share of the rim: a mirror camera's reflection is 5% of it at least
        share = circles.cutoff.radius / circles.outer.radius
        cutoff = f"{circles.cutoff.radius:.2f} px ({share:.0%} of the outer radius)"
    click.echo(f"centre: {u0:.2f} {v0:.2f}")
    click.echo(f"cut-off radius: {cutoff}")
    click.echo(
        f"outer radius: {circles.outer.radius:.2f} px (fit RMS {circles.outer.rms_px:.2f} px, "
        f"{circles.outer.inliers} of {circles.outer.rays} rays)"
    )
    if circles.cropped_by:
        edges = " and ".join(circles.cropped_by)
        click.echo(
            f"the frame cuts the image circle at its {edges} edge{'s' if len(circles.cropped_by) > 1 else ''}: "
            f"{circles.rim_in_frame:.0%} of the rim lies in the frame, the valid region is the circle within the frame"
        )
    click.echo(f"rim seen on {circles.rim_seen:.0%} of the rays, {circles.rim_polarity}")
    half = side_by_side_half(circles.centre, (int(omni.shape[1]), int(omni.shape[0])))
    if half is not None:
        click.echo(
            f"this is the {half} lens of a frame of two side by side (a dual fisheye's raw frame?): "
            "a rig of them takes import --side-by-side or rig learn --side-by-side"
        )
    if circles.ellipse is not None:
        e = circles.ellipse
        click.echo(
            f"the rim is an ellipse: semi-axes {e.semi_axes[0]:.2f} and {e.semi_axes[1]:.2f} px, "
            f"angle {e.angle_deg:.1f} deg"
        )
    if overlay is not None:
        say(f"wrote {overlay}")


def find_image_circles_in(path: Path, image: Any) -> ImageCircles:
    """Find the image circles, naming the file in any error."""
    try:
        return find_image_circles(image)
    except PanomapError as exc:
        raise PanomapError(exc.detail, path) from None


def _image_size(size: tuple[int, int] | None) -> tuple[int, int] | None:
    if size is not None:
        width, height = size
        if width <= 0 or height <= 0:
            raise click.BadParameter(f"{width}x{height}: must be positive", param_hint="'--image-size'")
    return size


def _describe_fit(table: PanoMappingTable) -> str:
    """The fit: the model chosen, the azimuth mapping, every landmark's residual, and the table."""
    fit = table_fit_report(table)
    if fit is None:
        raise PanomapError("the table holds no fit report")
    selection = fit.model_selection_loo_rms_px
    if fit.lines is not None and fit.azimuth_mode != "lines" and fit.lines.model_selection_cv_rms_px:
        ranked = _ranked(fit.lines.model_selection_cv_rms_px)
        chosen = f"radial model: {fit.model} (chosen over the image's lines, held-out RMS px: {ranked})"
    elif selection:
        chosen = f"radial model: {fit.model} (leave-one-out RMS px: {_ranked(selection)})"
    else:
        chosen = f"radial model: {fit.model} (forced)"
    mirrored = "mirrored" if fit.s == -1 else "not mirrored"
    azimuth = (
        f"camera looks {fit.axis} ({fit.axis_source}); azimuth mapping phi = "
        f"{'-' if fit.s == -1 else ''}theta {fit.phi0_deg:+.2f} deg "
        f"({mirrored}, {'fitted' if fit.azimuth_mode == 'fit' else 'assumed as in the paper'}; "
        f"consistency {fit.azimuth_consistency:.3f})"
    )
    lines = [chosen, azimuth]
    centre = fit.centre_sentence()
    if centre is not None:
        lines.append(centre)
    if fit is not None and fit.mount is not None:
        lines.extend(fit.mount.sentences())
    if fit.viewpoint is not None:
        lines.extend(fit.viewpoint.sentences())
    return "\n".join([*lines, _describe_residuals(table, fit)])


def _checked_terms(value: str) -> str:
    """``--terms``: 'auto', 'none' or known terms' names joined by commas (a usage error otherwise)."""
    if value in ("auto", "none"):
        return value
    try:
        return ",".join(check_term_names([name.strip() for name in value.split(",") if name.strip()]))
    except PanomapError as exc:
        raise click.BadParameter(str(exc)) from None


def _ranked(scores: Mapping[str, float | None]) -> str:
    """Each model's score (px), best first; '-' where it could not serve."""
    ordered = sorted(scores.items(), key=lambda kv: (kv[1] is None, kv[1] or 0))
    return ", ".join(f"{k} {v:.3f}" if v is not None else f"{k} -" for k, v in ordered)


def _describe_residuals(table: PanoMappingTable, fit: FitReport | None) -> str:
    """Every landmark's residual, their RMS and the radius's standard error (when there is a fit), and the table."""
    if fit is not None and fit.lines is not None and fit.azimuth_mode == "lines":
        lines = [*fit.lines.sentences(), _describe_table(table)]
        return "\n".join(lines)
    rows = () if fit is None else fit.landmarks
    width = max([12, *(len(row.name) for row in rows)])  # whole names: a cut one can name two landmarks
    lines = [f"{'landmark':<{width}} {'u':>9} {'v':>9} {'elev deg':>9} {'azim deg':>9} {'resid px':>9}"]
    for row in rows:
        lines.append(
            f"{row.name:<{width}} {row.u:9.2f} {row.v:9.2f} {row.elevation_deg:9.2f} "
            f"{row.azimuth_deg:9.2f} {row.residual_px:9.3f}" + ("  OUTLIER (not used)" if row.outlier else "")
        )
    if fit is not None and fit.outliers:
        lines.append(f"outliers dropped: {', '.join(fit.outliers)}")
    rms, largest = (math.nan, math.nan) if fit is None else (fit.rms_px, fit.max_px)
    lines.append(f"residuals: RMS {rms:.3f} px, max {largest:.3f} px")
    if fit is not None and fit.lines is not None:
        joined = fit.lines
        lines.append(
            f"{len(joined.lines)} straight lines of the image joined the fit ({len(joined.rejected)} arcs set aside): "
            f"RMS {joined.rms_px:.2f} px, max {joined.max_px:.2f} px from their planes; edge noise "
            f"{joined.sigma_px:.2f} px"
        )
    uncertainty = None if fit is None else fit.uncertainty
    if uncertainty is not None:
        inside = uncertainty.max_se_in_landmark_range_px
        lines.append(
            "radius standard error: up to "
            + (f"{inside:.2f} px within the landmarks' elevations, " if inside is not None else "")
            + f"up to {uncertainty.max_se_px:.2f} px over the table's range"
        )
    lines.append(_describe_table(table))
    return "\n".join(lines)


def _describe_table(table: PanoMappingTable) -> str:
    m, n = table.size
    rho_s, rho_e = (round(math.degrees(x), 2) + 0.0 for x in table.elevation_range)  # (no "-0.00")
    sources = table.info.get("sources", {})
    return (
        f"table: {m} x {n} entries, elevation {rho_s:.2f}..{rho_e:.2f} deg, "
        f"cut-off radius {table.cutoff_radius:.1f} px ({sources.get('cutoff_radius', '?')}), "
        f"outer radius {table.outer_radius:.1f} px ({sources.get('outer_radius', '?')})"
    )


# ----------------------------------------------------------------------------- info


def _describe_viewpoint(table: PanoMappingTable, report: FitReport | None) -> list[str]:
    """Whether the table's camera has a single viewpoint, and what a single-viewpoint table would miss."""
    if report is not None and report.viewpoint is not None:
        return report.viewpoint.sentences()
    if table.model.single_viewpoint:
        return ["viewpoint: single (every ray from the camera position)"]
    viewpoint = table.model.viewpoint
    assert viewpoint is not None
    low, high = viewpoint.elevations_rad[0], viewpoint.elevations_rad[-1]
    return [f"viewpoint: not single: the rays leave the axis over {viewpoint.excursion(low, high):.4g} world units"]


def _looks(model: CameraModel) -> str:
    """Where the camera's optical axis looks in the world, in words: straight down or up, or its pitch from the
    horizon toward the azimuth of its yaw (the orientation of docs/conventions.md, ``orient``/``--orientation``)."""
    yaw_deg, pitch_deg, _ = (math.degrees(a) for a in model.orientation)
    if abs(abs(pitch_deg) - 90.0) < 0.005:
        return f"straight {'down' if pitch_deg < 0 else 'up'}"
    toward = f"toward azimuth {round(yaw_deg, 2) % 360.0:.2f} deg"  # (rounded first: -0.001 is 0.00, not 360.00)
    if abs(pitch_deg) < 0.005:
        return f"ahead, {toward}"
    return f"{abs(pitch_deg):.2f} deg {'below' if pitch_deg < 0 else 'above'} the horizon, {toward}"


def _describe_import(record: object) -> list[str]:
    """Where an imported table came from (``panomap import``): none for a table fitted here."""
    if not isinstance(record, dict):
        return []
    camera = f", camera {record['camera']}" if record.get("camera") is not None else ""
    return [
        f"imported from {record.get('file', '?')} ({record.get('format', '?')} calibration{camera}, sha256 "
        f"{str(record.get('sha256', '?'))[:12]}...): model {record.get('model', '?')}"
        f"{' (a mirror camera: its frame is the world mirrored)' if record.get('mirror') else ''}; the radial "
        f"model below approximates it within "
        f"{float(record.get('radial_approximation_max_px', float('nan'))):.2f} px (the entries are exact)"
    ]


@click.command()
@click.argument("table", type=PATH)
@click.option("--json", "as_json", is_flag=True, help="Print the metadata as JSON.")
@click.option(
    "--uncertainty-plot",
    type=PATH,
    help="Also write the projection uncertainty figure (PNG) of a table learned from checkerboards.",
)
def info(table: Path, as_json: bool, uncertainty_plot: Path | None = None) -> None:
    """Print a table's metadata: model, centre, s, phi0, range, sizes, landmarks and residuals (a rig's: its
    cameras, where each sits and looks, what each sees, their overlaps)."""
    from ..rig.file import is_rig_file
    from .rigs import describe_rig_file

    if is_rig_file(table):
        if uncertainty_plot is not None:
            raise click.UsageError("--uncertainty-plot draws a table's camera; a rig file holds several")
        describe_rig_file(table, as_json)
        return
    loaded = load_table(table)
    if uncertainty_plot is not None:
        from ..io.uncertainty_plot import save_uncertainty_plot

        if uncertainty_plot.suffix.lower() != ".png":
            raise click.BadParameter(
                f"{uncertainty_plot}: the figure is written as PNG (name it .png)", param_hint="'--uncertainty-plot'"
            )
        check_outputs([("the table", table)], [("--uncertainty-plot", uncertainty_plot)])
        save_uncertainty_plot(loaded, uncertainty_plot, table)
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
        f"radial model: {model.radial.kind} of the angle from the optical axis, coefficients "
        + ", ".join(f"{c:.9g}" for c in model.radial.coefficients),
        f"azimuth mapping: s = {model.s:+d}, phi0 = {math.degrees(model.phi0):.4f} deg",
    ]
    tilt_rad, toward_rad = model.tilt
    lines.extend(_describe_import(loaded.info.get("import")))
    lines.append(
        f"camera axis: vertical (level), looking {_looks(model)}"
        if model.rotation is None
        else f"camera axis: {math.degrees(tilt_rad):.3f} deg off the vertical, leaning toward azimuth "
        f"{round(math.degrees(toward_rad), 2) % 360.0:.2f} deg, looking {_looks(model)} (the table is in world angles)"
    )
    yaw, pitch, roll = (round(math.degrees(a), 3) + 0.0 for a in model.orientation)  # (no "-0.000")
    rho_s, rho_e = (round(math.degrees(x), 2) + 0.0 for x in loaded.elevation_range)
    lines.append(
        f"orientation: yaw {yaw:.3f}, pitch {pitch:.3f}, roll {roll:.3f} deg (as a perspective view's; "
        f"the table spans elevations {rho_s:.2f}..{rho_e:.2f} deg)"
    )
    report = table_fit_report(loaded, table)
    if report is not None and report.mount is not None and report.mount.position_refined:
        lines.append(f"camera position refined from {tuple(round(c, 6) for c in report.mount.camera_given)}")
    lines.extend(_describe_viewpoint(loaded, report))
    # An imported table has no landmarks: its table line instead of their residuals.
    last = _describe_table(loaded) if "import" in loaded.info else _describe_residuals(loaded, report)
    click.echo(printable("\n".join([*lines, last]), keep="\n"))
