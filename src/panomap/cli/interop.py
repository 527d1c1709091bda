"""``panomap import`` and ``panomap export``: other tools' calibrations in and out."""

from __future__ import annotations

import math
from pathlib import Path

import click

from ..calibrate.circles import ImageCircles, NoImageCircle, find_image_circles
from ..calibrate.circles.side_by_side import side_by_side_half
from ..calibrate.level import level_table
from ..errors import PanomapError, printable
from ..files import all_or_none, check_outputs
from ..interop.api import check_image_size, could_be_a_mirror_camera, table_of_imported
from ..interop.export import FORMATS, export_calibration
from ..interop.orient import orient_table
from ..interop.readers import READERS, Imported, read_calibration
from ..interop.table_of_camera import model_profile, radius_of_fov
from ..io.images import MAX_IMAGE_PIXELS
from ..rig.file import is_rig_file
from ..table.file import is_table_file, load_table, save_table
from ..table.table import check_table_size
from .calibrate import find_image_circles_in
from .options import (
    FINITE,
    NON_NEGATIVE,
    PATH,
    SIZE,
    TILT,
    Finite,
    check_radii,
    check_room_as,
    check_table_outputs,
    orientation_option,
    orientation_rad,
    read_omni,
    refuse_same_input,
    say,
    say_note,
    usage_error,
)
from .rigs import import_rig, rig_format


@click.command("import")
@click.argument("calibration", type=PATH)
@click.option("-o", "--output", type=PATH, required=True, help="Table file to write (.npz).")
@click.option(
    "--format", "format_", type=click.Choice(list(READERS)), help="The file's format [default: from its content]."
)
@click.option(
    "--camera-name",
    help="The camera of a Kalibr camchain or a Basalt calibration (a name, or a Basalt index) [default: the first].",
)
@click.option("--camera-id", help="The camera of a COLMAP cameras.txt [default: the first].")
@orientation_option(
    "Where the camera looks, in degrees, as a perspective view's yaw (azimuth of the optical axis, "
    "counter-clockwise from +X), pitch (0 ahead, -90 straight down, 90 up) and roll (the image's right dipped): "
    "'0 0 0' for a fisheye looking ahead along +X [default: straight down, as '90 -90 0', unless --axis or --tilt]."
)
@click.option(
    "--axis",
    type=click.Choice(["down", "up"]),
    help="Straight down or up: the optical axis becomes the table's vertical (azimuth 0 along the image's "
    "columns) [default: down].",
)
@click.option(
    "--tilt",
    type=TILT,
    default="none",
    show_default=True,
    metavar="none|'DEG AZ_DEG'",
    help="The mount: the optical axis DEG off the vertical, leaning toward world azimuth AZ_DEG (one quoted argument).",
)
@click.option(
    "--camera",
    nargs=3,
    type=FINITE,
    default=(0.0, 0.0, 0.0),
    metavar="X0 Y0 Z0",
    help="Camera (lens centre) position in world units [default: 0 0 0].",
)
@click.option(
    "--image",
    "images",
    type=PATH,
    multiple=True,
    help="An image of the camera: its size is checked against the calibration's, and its image circle and "
    "cut-off disc (when found) bound the table [default: the model's valid range in the image]. A rig takes its "
    "frame (--side-by-side) or one picture per camera (--image each time): each lens's circle bounds its table, "
    "and a camchain's poses are checked against the pictures.",
)
@click.option(
    "--mirror/--lens",
    "mirror",
    default=None,
    help="A mirror camera (a camera looking into a mirror: its image, and its calibration's frame, are the world's "
    "mirror image, turned back in the table) or a lens [default: a mirror camera where --image shows a cut-off "
    "disc (the camera's own reflection), else a lens].",
)
@click.option(
    "--image-size",
    type=SIZE,
    metavar="WxH",
    help="The images' size (px), where there is no --image: checked against the calibration's, and needed "
    "for a file that gives none (an OpenCV omnidir file).",
)
@click.option("--cutoff-radius", type=NON_NEGATIVE, help="Radius (px) of the cut-off disc about the principal point.")
@click.option("--outer-radius", type=NON_NEGATIVE, help="Radius (px) of the image circle about the principal point.")
@click.option("--table-size", type=SIZE, metavar="MxN", help="Table size [default: about one entry per pixel].")
@click.option(
    "--side-by-side",
    is_flag=True,
    help="A rig (a camchain of several cameras): their pictures come side by side in one frame, camera 0 on the "
    "left (a dual-fisheye camera's raw frame).",
)
@click.option(
    "--fov",
    "fov_deg",
    type=Finite(0.0, open=True),
    metavar="DEG",
    help="A lens's field of view across (a 360 camera's: 190-200); its table stops there (as --outer-radius at that "
    "angle), so that its black rim does not join a rig's blend [default: its circle in --image, else the model's "
    "range]. A rig: each lens's.",
)
def import_(
    calibration: Path,
    output: Path,
    format_: str | None,
    camera_name: str | None,
    camera_id: str | None,
    orientation: tuple[float, float, float] | None,
    axis: str | None,
    tilt: str | tuple[float, float],
    camera: tuple[float, float, float],
    images: tuple[Path, ...],
    image_size: tuple[int, int] | None,
    cutoff_radius: float | None,
    outer_radius: float | None,
    table_size: tuple[int, int] | None,
    side_by_side: bool,
    fov_deg: float | None,
    mirror: bool | None,
) -> None:
    """Make a table from a calibration: OCamCalib calib_results.txt, a Kalibr camchain, an OpenCV
    cv::fisheye or cv::omnidir FileStorage file, COLMAP cameras.txt, a BoofCV calibration YAML
    (omnidirectional_universal, kannala_brandt), a Basalt calibration JSON (ds, eucm, ucm, kb4,
    pinhole-radtan8, pinhole), a gyroflow lens profile (opencv_fisheye), a Hugin .pto project (rectilinear and
    fisheye images) or an OpenCalib (PJLab) OCam intrinsic JSON. A file of several cameras makes a rig (one file,
    every camera's table in one world): a Kalibr camchain (each camera's T_cn_cnm1) or a Basalt calibration (each
    camera's T_imu_cam), --orientation and --camera placing camera 0, looking ahead along +X by default; a Hugin
    project in its own world (its yaw, pitch and roll). --camera-name picks one camera instead."""
    if tilt == "fit":
        raise click.BadParameter(
            "an imported camera's tilt is given, not fitted: 'none' or 'DEG AZ_DEG'", param_hint="'--tilt'"
        )
    if orientation is not None and (axis is not None or tilt != "none"):
        raise click.UsageError("give --orientation, or --axis and --tilt, not both")
    if camera_name is not None and camera_id is not None:
        raise click.UsageError("give --camera-name (Kalibr, Basalt) or --camera-id (COLMAP), not both")
    if images and image_size is not None:
        raise click.UsageError("give --image or --image-size, not both")
    if image_size is not None and not (min(image_size) > 0 and image_size[0] * image_size[1] <= MAX_IMAGE_PIXELS):
        raise click.BadParameter(
            f"{image_size[0]}x{image_size[1]} is not an image size (positive, at most {MAX_IMAGE_PIXELS} pixels)",
            param_hint="'--image-size'",
        )
    check_radii(cutoff_radius, outer_radius)
    if table_size is not None:
        try:
            check_table_size(table_size, what="--table-size")
        except PanomapError as exc:
            raise usage_error(exc) from None
    check_table_outputs(
        [("the calibration", calibration), *(("the image", image) for image in images)], output, "a table (or a rig)"
    )
    _not_panomaps_own(calibration)
    rig = rig_format(calibration, format_) if camera_name is None and camera_id is None else None
    if rig is not None:
        one_camera = {"--axis": axis, "--image-size": image_size, "--cutoff-radius": cutoff_radius}
        one_camera |= {"--outer-radius": outer_radius, "--tilt": None if tilt == "none" else str(tilt)}
        one_camera |= {"--mirror/--lens": mirror}
        given = [name for name, value in one_camera.items() if value is not None]
        if given:
            raise click.UsageError(f"{', '.join(given)}: for one camera; a rig takes --orientation, --fov, --image")
        import_rig(calibration, rig, output, orientation=orientation, camera=camera, side_by_side=side_by_side,
                   fov_deg=fov_deg, images=images, table_size=table_size,
                   find_circles=find_image_circles_in)  # fmt: skip
        return
    if side_by_side:
        raise click.UsageError("--side-by-side is for a rig (a file of several cameras)")
    if fov_deg is not None and (outer_radius is not None or mirror):
        raise click.UsageError("--fov is a lens's field of view across: give it or --outer-radius, and not --mirror")
    if len(images) > 1:
        raise click.UsageError(f"one camera takes one --image, not {len(images)}")
    image = images[0] if images else None
    axis = axis or "down"
    sources: dict[str, str] = {}
    imported = read_calibration(calibration, format_, camera_name or camera_id)
    if fov_deg is not None:  # (a lens's: no cut-off disc makes it a mirror camera)
        outer_radius, mirror = _outer_radius_of_fov(imported, fov_deg, calibration), False
    if image is not None:
        image_size, cutoff_radius, outer_radius, mirror = _bounds_of_image(
            imported, calibration, image, (cutoff_radius, outer_radius), mirror, sources
        )
    if fov_deg is not None:
        sources["outer_radius"] = f"--fov {fov_deg:g} deg"
    table = table_of_imported(
        imported,
        calibration,
        axis=axis,
        tilt_rad=(0.0, 0.0) if isinstance(tilt, str) else (math.radians(tilt[0]), math.radians(tilt[1])),
        orientation_rad=orientation_rad(orientation),
        camera_position=camera,
        image_size=image_size,
        cutoff_radius=cutoff_radius,
        outer_radius=outer_radius,
        size=table_size,
        sources=sources,
        mirror=bool(mirror),
    )
    for note in imported.notes:  # (once the table is made: a refusal is one line)
        say_note(f"{printable(note)}")
    if image is None and mirror is None and _could_be_a_mirror(imported, image_size, outer_radius):
        # Nothing says which, and the model sees beyond 90 deg off its axis, as a mirror camera does: say so.
        say_note("taken as a lens; a mirror camera's needs --mirror (or --image)")
    with all_or_none():
        save_table(table, output)
    record = table.info["import"]
    m, n = table.size
    rho_s, rho_e = (round(math.degrees(x), 2) + 0.0 for x in table.elevation_range)  # (no "-0.00")
    say(
        printable(
            f"{calibration}: {record['format']} calibration, model {record['model']}"
            + (f" (camera {record['camera']})" if "camera" in record else "")
            + f"; table {m} x {n}, elevation {rho_s:.2f}..{rho_e:.2f} deg, radii {table.cutoff_radius:.1f}.."
            f"{table.outer_radius:.1f} px"
        )
    )
    if mirror:  # on a line of its own: the summary above is long enough
        say(printable(f"{sources.get('handedness', 'a mirror camera')} (its world turned back: s = +1)"))
    say(f"wrote {output}")


def _outer_radius_of_fov(imported: Imported, fov_deg: float, calibration: Path) -> float:
    """The image circle (px about the principal point) where the lens sees ``fov_deg / 2`` off its axis.

    Raises
    ------
    PanomapError
        Where the model stops short of that angle (a pinhole sees less than 90 deg off its axis).
    """
    radius_px, half_rad = radius_of_fov(imported.model, math.radians(fov_deg))
    if math.degrees(half_rad) < fov_deg / 2 - 0.05:
        raise PanomapError(
            f"--fov {fov_deg:g}: the {imported.model.name} model sees at most {math.degrees(half_rad):.1f} deg off its "
            f"axis; give --fov {math.floor(2 * math.degrees(half_rad)):g} or less",
            calibration,
        )
    return radius_px


MIRROR_MODELS = ("ocam", "mei")
"""The models that calibrate mirror cameras as well as lenses (OCamCalib's, the unified model): nothing in their
files says which."""


def _could_be_a_mirror(imported: Imported, image_size: tuple[int, int] | None, outer_radius: float | None) -> bool:
    """Whether the choice of a mirror camera or a lens could matter: a model of either kind that sees beyond 90 deg
    off its axis within the image circle (or the frame), as every mirror camera does and no lens of 180 deg or
    less (:func:`~panomap.interop.api.could_be_a_mirror_camera`)."""
    return imported.model.name in MIRROR_MODELS and could_be_a_mirror_camera(imported, image_size, outer_radius)


def _bounds_of_image(
    imported: Imported,
    calibration: Path,
    image: Path,
    radii: tuple[float | None, float | None],
    mirror: bool | None,
    sources: dict[str, str],
) -> tuple[tuple[int, int], float | None, float | None, bool | None]:
    """The image's size, the (cut-off, outer) radii its circles give (unless given), and whether it is a mirror
    camera's (unless given: where a cut-off disc, the camera's own reflection, shows)."""
    cutoff_radius, outer_radius = radii
    omni = read_omni(image)
    image_size = (int(omni.shape[1]), int(omni.shape[0]))
    check_image_size(imported, image_size, calibration)
    try:
        circles = find_image_circles(omni)
    except PanomapError as exc:  # no rim (a full-frame fisheye, a mirror overfilling the frame)
        seen = exc.seen if isinstance(exc, NoImageCircle) else exc.detail  # the centre is the calibration's
        say_note(f"{image.name}: {printable(seen)}; the table covers the model's range")
        cutoff = exc.cutoff if isinstance(exc, NoImageCircle) else None
        if cutoff is not None and cutoff_radius is None:
            u0, v0 = imported.model.principal_point
            cutoff_radius = cutoff.radius + math.hypot(cutoff.centre[0] - u0, cutoff.centre[1] - v0)
            sources["cutoff_radius"] = f"cut-off disc found in {image.name}"
    else:
        cutoff = circles.cutoff
        if _one_of_two(image, circles, imported.model.principal_point, image_size, outer_radius is not None):
            cutoff_radius, outer_radius = _circle_radii(
                imported.model.principal_point, circles, cutoff_radius, outer_radius, sources, image
            )
        else:
            cutoff = None
        outer_radius = _within_model(imported, outer_radius, sources)
    if mirror is None and cutoff is not None:
        mirror = True
        size = f"{cutoff.radius:.0f} px" if outer_radius is None else f"{cutoff.radius / outer_radius:.0%} of the rim"
        sources["handedness"] = f"a mirror camera assumed: a cut-off disc ({size}) in {image.name}; --lens if not"
    elif mirror is None and _could_be_a_mirror(imported, image_size, outer_radius):  # either kind, no disc
        say_note(f"{image.name}: no cut-off disc (a mirror's reflection of its camera): taken as a "
                   "lens; --mirror if not")  # fmt: skip
    return image_size, cutoff_radius, outer_radius, mirror


def _one_of_two(
    image: Path,
    circles: ImageCircles,
    principal_point: tuple[float, float],
    image_size: tuple[int, int],
    outer_given: bool,
) -> bool:
    """Whether the circle found in ``image`` is the calibration's own. In a frame of two lenses side by side (a dual
    fisheye's raw frame) a note says which lens's circle was taken and that the pair is a rig; where the
    calibration's principal point lies in the other half the circle is the other lens's: not taken, and without
    the outer radius given the table, which would reach into the other lens, is refused."""
    half = side_by_side_half(circles.centre, image_size)
    if half is None:
        return True
    mine = "left" if principal_point[0] < image_size[0] / 2.0 else "right"
    rig = "both lenses, a rig, take import --side-by-side (docs/rigs.md)"
    if mine == half:
        say_note(f"{image}: two lenses side by side: the {half} one's circle taken; {rig}")
        return True
    if not outer_given:
        raise PanomapError(
            f"two lenses side by side: the circle found is the {half} one's, this calibration's the {mine} one's; "
            "give --outer-radius or import --side-by-side",
            image,
        )
    say_note(f"{image}: two lenses side by side: the {half} one's circle not taken; {rig}")
    return False


def _within_model(imported: Imported, outer_radius: float | None, sources: dict[str, str]) -> float | None:
    """The image circle found, no farther than the model's valid range (a found circle a few px beyond it: the
    table stops where the calibration does, and says so)."""
    if outer_radius is None or "outer_radius" not in sources:
        return outer_radius
    profile = model_profile(imported.model)
    reach = float(profile.radius[-1])
    if outer_radius <= reach:
        return outer_radius
    say_note(
        f"the image circle ({outer_radius:.1f} px) reaches beyond the {imported.model.name} model's "
        f"valid range; the table stops there ({reach:.1f} px, {math.degrees(profile.alpha[-1]):.1f} deg off the axis)"
    )
    sources["outer_radius"] += f", cut to the {imported.model.name} model's valid range"
    return reach


def _circle_radii(
    principal_point: tuple[float, float],
    circles: ImageCircles,
    cutoff_radius: float | None,
    outer_radius: float | None,
    sources: dict[str, str],
    image: Path,
) -> tuple[float | None, float | None]:
    """The annulus from the image's circles, about the calibration's principal point (the largest circle
    about it inside the rim, the smallest outside the cut-off disc), unless the radii are given."""
    u0, v0 = principal_point
    offset = math.hypot(circles.centre[0] - u0, circles.centre[1] - v0)
    if outer_radius is None and circles.rim_seen > 0.25:
        outer_radius = circles.outer.radius - offset
        sources["outer_radius"] = f"image circle found in {image.name}"
    if cutoff_radius is None and circles.cutoff is not None:
        cutoff_radius = circles.cutoff.radius + offset
        sources["cutoff_radius"] = f"cut-off disc found in {image.name}"
    return cutoff_radius, outer_radius


@click.command("orient")
@click.argument("table", type=PATH)
@click.option("-o", "--output", type=PATH, required=True, help="Table file to write (.npz).")
@orientation_option(
    "Where the camera looks, in degrees, as a perspective view's yaw (azimuth of the optical axis, "
    "counter-clockwise from +X), pitch (0 ahead, -90 straight down, 90 up) and roll (the image's right dipped).",
    required=True,
)
def orient(table: Path, output: Path, orientation: tuple[float, float, float]) -> None:
    """Turn a table's camera to look another way, without a new fit: its entries made anew from its model (or
    its calibration's), over every world direction it then sees."""
    check_table_outputs([("the table", table)], output)
    loaded = load_table(table)
    yaw, pitch, roll = orientation_rad(orientation)  # type: ignore[misc]
    try:
        turned = orient_table(loaded, yaw, pitch, roll)
    except PanomapError as exc:
        raise PanomapError(exc.detail, exc.source or table) from None
    with all_or_none():
        save_table(turned, output)
    rho_s, rho_e = (round(math.degrees(x), 2) + 0.0 for x in turned.elevation_range)  # (no "-0.00")
    say(
        f"{printable(str(table))}: looking yaw {orientation[0]:g}, pitch {orientation[1]:g}, roll "
        f"{orientation[2]:g} deg; table {turned.size[0]} x {turned.size[1]}, elevation {rho_s:.2f}..{rho_e:.2f} deg"
    )
    say(f"wrote {printable(str(output))}")


@click.command("level")
@click.argument("table", type=PATH)
@click.argument("images", type=PATH, nargs=-1, required=True)
@click.option("-o", "--output", type=PATH, required=True, help="Table file to write (.npz).")
def level(table: Path, images: tuple[Path, ...], output: Path) -> None:
    """Level a table from the vertical lines of pictures of its camera (door and window frames, wall corners,
    poles): the camera's pitch and roll found, its yaw kept. The table's orientation must be within 20 deg of
    the truth (give it with panomap orient or import --orientation); several pictures are pooled."""
    check_table_outputs([("the table", table), *(("an image", image) for image in images)], output)
    refuse_same_input(images, "picture", "its lines twice count twice", lambda _: "'IMAGES...'")
    loaded = load_table(table)
    check_room_as(output, table)
    pictures = []
    for image in images:
        picture = read_omni(image)
        if loaded.image_size is not None and (picture.shape[1], picture.shape[0]) != tuple(loaded.image_size):
            raise PanomapError(
                f"it is {picture.shape[1]} x {picture.shape[0]}, the table is for "
                f"{loaded.image_size[0]} x {loaded.image_size[1]} images",
                image,
            )
        pictures.append(picture)
    result = level_table(loaded, pictures, [image.name for image in images])
    with all_or_none():
        save_table(result.table, output)
    yaw, pitch, roll = result.orientation_deg
    say(
        f"levelled from {result.vertical_lines} vertical lines (of {result.straight_lines} straight edges): "
        f"yaw {yaw:.2f} (kept), pitch {pitch:.2f}, roll {roll:.2f} deg; the axis turned "
        f"{result.turned_deg:.2f} deg, sure within {result.uncertainty_deg:.2f} deg (95%)"
    )
    say(f"wrote {printable(str(output))}")


@click.command("export")
@click.argument("table", type=PATH)
@click.option("-o", "--output", type=PATH, required=True, help="Calibration file to write.")
@click.option("--format", "format_", type=click.Choice(list(FORMATS)), required=True, help="The tool's model.")
def export(table: Path, output: Path, format_: str) -> None:
    """Write a table's camera in another tool's model, fitted to the table over its valid range; print the
    largest difference (px) between the two over that range."""
    check_outputs([("the table", table)], [("the output", output)])
    loaded = load_table(table)
    try:
        result = export_calibration(loaded, output, format_)
    except PanomapError as exc:
        raise PanomapError(exc.detail, exc.source or table) from None
    for note in result.notes:
        say_note(f"{note}")
    parameters = ", ".join(
        f"{k} = {v:.6g}" if isinstance(v, float) else f"{k} = [{', '.join(f'{x:.6g}' for x in v)}]"
        for k, v in result.model.parameters().items()
    )
    say(f"{format_} ({result.model.name}): {parameters}")
    say(f"largest difference from the table over its valid range: {result.max_error_px:.4f} px")
    say(f"wrote {output}")


def _not_panomaps_own(path: Path) -> None:
    """Refuse, in one line, a rig or a table that panomap wrote: ``import`` reads other tools' calibrations."""
    if is_rig_file(path):
        raise PanomapError("a panomap rig already: the views, video and batch take it as it is", path)
    if is_table_file(path):
        raise PanomapError("a panomap table already: the views take it as it is (panomap orient turns it)", path)
