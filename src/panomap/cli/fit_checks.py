"""``panomap fit``'s options checked before any work: what goes with landmarks, what with pictures, a picture given
as LANDMARKS, folders and globs for ``--image``, the mount and the ray origins asked for together.

Options missing, out of range or not going together are usage errors (exit 2).
"""

from __future__ import annotations

import glob
import math
from pathlib import Path

import click
from click.core import ParameterSource

from ..calibrate.core.table_range import DEFAULT_MAX_SIZE
from ..calibrate.landmarks.viewpoint import SphericalMirror, viewpoint_conflict
from ..camera.radial_models import radial_kind
from ..errors import PanomapError, printable
from ..files import check_room, expand_input, kind_of
from ..table.file import ENTRY_BYTES
from ..table.table import check_table_size
from .options import check_table_outputs, orientation_rad, usage_error


def check_mount_options(
    model: str,
    azimuth: str,
    axis: str | None,
    tilt: str | tuple[float, float],
    orientation: tuple[float, float, float] | None,
    viewpoint: str,
    sphere_radius: float | None,
) -> str | None:
    """A landmark fit's mount and ray origins checked together; the ray origins asked for, in words (None: a
    single viewpoint or the automatic choice)."""
    mirror = _mirror_kind(viewpoint, sphere_radius)
    if orientation is not None and (axis is not None or not isinstance(tilt, str)):
        raise click.UsageError("give --orientation, or --axis and a --tilt pair, not both")
    orientation_rad(orientation)  # (checks the pitch)
    conflict = viewpoint_conflict(
        model, azimuth, viewpoint if sphere_radius is None else SphericalMirror(sphere_radius)
    )
    if conflict is not None:
        raise click.UsageError(conflict)
    return mirror


def refuse_picture_as_landmarks(landmarks: Path | None) -> None:
    """A picture given as LANDMARKS (``fit room.jpg``, or ``--image a.jpg b.jpg``): one line pointing to --image."""
    if landmarks is not None and kind_of(landmarks) is not None:
        raise click.UsageError(
            f"{printable(str(landmarks))} is a picture, not landmarks (CSV u,v,X,Y,Z or JSON): give it as --image "
            f"{printable(str(landmarks))} (one --image per picture, or a folder, or a quoted glob)"
        )


def expand_images(patterns: tuple[str, ...]) -> tuple[Path, ...]:
    """Each --image as the pictures it names: a file as given, a folder's pictures, a glob's matches, in order (a
    picture named twice is refused later); a folder or a glob that names none is a usage error."""
    found: list[Path] = []
    for pattern in patterns:
        if Path(pattern).is_dir() or (glob.has_magic(pattern) and not Path(pattern).exists()):
            try:
                found += expand_input(pattern, kinds=("image",))
            except PanomapError as exc:
                raise usage_error(exc, "--image") from None
        else:
            found.append(Path(pattern))
    return tuple(found)


# The options of a landmark fit that learning from lines (no LANDMARKS) does not use: the lines find the centre,
# the annulus, the tilt and the table's size themselves, and know no position.
LANDMARK_ONLY = (
    "camera", "centre", "image_size", "table_size", "cutoff_radius", "outer_radius", "azimuth", "refine_centre",
    "pixel_sigma", "world_sigma", "tilt", "camera_sigma", "viewpoint", "sphere_radius", "keep_outliers",
    "orientation",
)  # fmt: skip


def _mirror_kind(viewpoint: str, sphere_radius: float | None) -> str | None:
    """The ray origins the landmark fit is asked to fit, in words; None for a single viewpoint or its automatic
    choice (usage error, exit 2, where --sphere-radius and a --viewpoint other than auto are both given)."""
    if sphere_radius is not None:
        if viewpoint != "auto":
            raise click.UsageError(
                f"--sphere-radius fits the sphere's ray origins: --viewpoint {viewpoint} does not go with it"
            )
        return "a spherical mirror's ray origins (--sphere-radius)"
    return "the fitted ray origins (--viewpoint caustic)" if viewpoint == "caustic" else None


def refuse_landmark_options(context: click.Context) -> None:
    """Refuse, as a usage error naming them, the landmark fit's options given to a fit from lines (it
    would ignore them)."""
    given = [
        "/".join(param.opts[:1] + param.secondary_opts[:1])
        for param in context.command.params
        if param.name in LANDMARK_ONLY
        and context.get_parameter_source(param.name) in (ParameterSource.COMMANDLINE, ParameterSource.ENVIRONMENT)
    ]
    if given:
        raise click.UsageError(
            f"{', '.join(given)}: for a fit to LANDMARKS; learning from lines (no LANDMARKS) does not use "
            + ("it" if len(given) == 1 else "them")
            + " (it finds the centre, the annulus and the tilt itself; --camera-height gives the camera's height)"
        )


def check_landmark_fit_options(
    landmarks: Path,
    output: Path,
    images: tuple[Path, ...],
    centre: tuple[float, float] | None,
    table_size: tuple[int, int] | None,
    model: str,
    refine_centre: bool | None,
    plot: Path | None,
    overlay: Path | None,
    azimuth_zero: tuple[float, float] | None,
    handedness: str,
    camera_height: float | None,
    terms: str = "auto",
    uncertainty_plot: Path | None = None,
    image_size: tuple[int, int] | None = None,
) -> Path | None:
    """The checks of a landmark fit's options before any work (usage errors, exit 2; outputs that are
    inputs, 1); returns its --image, if any."""
    if uncertainty_plot is not None:
        raise click.UsageError("--uncertainty-plot draws a camera learned from checkerboards (--image, no LANDMARKS)")
    line_options = {"--azimuth-zero": azimuth_zero, "--camera-height": camera_height}
    automatic = {"--handedness": handedness, "--terms": terms}
    asked = [(name, value) for name, value in automatic.items() if value != "auto"]
    for name, value in (*line_options.items(), *asked):
        if value is not None:
            raise click.UsageError(f"{name} is for learning from lines (no LANDMARKS); a landmark fit learns it")
    if len(images) > 1:
        raise click.UsageError("a landmark fit takes one --image (several pool their lines only without LANDMARKS)")
    image = images[0] if images else None
    if centre is None and image is None:
        raise click.UsageError("no image centre: give --centre U0 V0, or --image OMNI to find it")
    if refine_centre is True and model != "auto" and radial_kind(model).centre_given:
        raise click.UsageError(f"the {model} model takes the centre as given; --refine-centre needs another model")
    if table_size is not None:
        try:
            check_table_size(table_size, what="--size")
        except PanomapError as exc:
            raise usage_error(exc) from None
    if overlay is not None and image is None:
        raise click.UsageError("--overlay draws the fit on --image: give --image OMNI too")
    check_table_outputs(
        [("the landmarks", landmarks), ("the image", image)],
        output,
        pictures=[("--plot", plot, "the fit plot"), ("--overlay", overlay, "the overlay")],
    )
    if image_size is None and image is not None:
        from ..io.images import header_size

        image_size = header_size(image)
    check_table_room(output, table_size, image_size)
    return image


# Room for a table file's metadata (its model, its fit's report) beside its entries.
TABLE_METADATA_BYTES = 65_536


def check_table_room(output: Path, table_size: tuple[int, int] | None, image_size: tuple[int, int] | None) -> None:
    """Refuse, before the fit, a table its disk has no room for: one of ``table_size`` (M, N) where given,
    else the most a fit chooses for pictures of ``image_size`` (W, H): 2 pi R by R entries for R their half
    diagonal (the image circle's radius at most, but for a fisheye's circle past the frame's corners), within
    :data:`DEFAULT_MAX_SIZE` (that size where the pictures' is not known)."""
    if table_size is not None:
        check_room([(output, table_size[0] * table_size[1] * ENTRY_BYTES)])
        return
    m, n = DEFAULT_MAX_SIZE
    if image_size is not None:
        reach = math.hypot(*image_size) / 2
        m, n = min(8 * math.ceil(2 * math.pi * reach / 8), m), min(math.ceil(reach), n)
    check_room([(output, m * n * ENTRY_BYTES + TABLE_METADATA_BYTES)], up_to=True)
