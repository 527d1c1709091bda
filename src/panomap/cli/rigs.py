"""Rigs at the command line: the view commands given a rig file, and ``panomap import`` of a camchain of several
cameras (the rig's file, what ``info`` says of it)."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import click
import numpy as np

from ..errors import PanomapError, printable
from ..files import all_or_none, check_outputs, check_room, fill_pattern, read_text
from ..io.images import (
    check_image_output,
    image_file_bytes,
    map_file_bytes,
    read_rig_pictures,
    save_map,
    write_image,
)
from ..rig import CameraRig, RigRemapper, camera_maps, is_rig_file, load_rig, save_rig
from ..rig.blend import rig_view_bytes
from ..rig.rig import MAX_CAMERAS
from ..views import View
from .options import (
    check_memory_for,
    check_room_as,
    check_table_outputs,
    progress_bar,
    read_omni,
    refuse_same_input,
    refuse_video_as_picture,
    say,
    say_note,
    usage_error,
)

WRAPPING_KINDS = ("panorama", "equirect")
# The views of directions that take a distance, where each camera's own position then counts.
DISTANCE_KINDS = ("panorama", "equirect", "perspective")


def render_rig(
    rig_path: Path,
    images: tuple[Path, ...],
    output: Path,
    save_map_path: Path | None,
    interp: str,
    sampling: str,
    view: View,
    each: str | None,
) -> None:
    """A view of a rig: each camera's map, blended (gains matched over the overlaps); ``each`` (a pattern with
    ``{camera}``) also writes each camera's own unblended view."""
    if each is not None:
        try:
            fill_pattern(each, "camera", "each camera's name", ())
        except PanomapError as exc:
            raise click.BadParameter(exc.detail, param_hint="'--each'") from None
    rig = load_rig(rig_path)
    outputs = [("the output", output), ("--save-map", save_map_path)]
    each_paths = fill_pattern(each, "camera", "each camera's name", rig.names) if each is not None else []
    outputs += [(f"--each for {name}", path) for name, path in zip(rig.names, each_paths, strict=False)]
    check_outputs([("the rig", rig_path), *(("a picture", image) for image in images)], outputs)
    size = view.output_size(rig.tables[0])  # (every camera takes camera 0's)
    check_room(map_file_bytes(size, save_map_path))
    check_memory_for(rig_view_bytes(size, rig.count), f"a view of {size[0]} x {size[1]} px of {rig.count} cameras")
    for path, option in ((output, "-o"), *((each_path, "--each") for each_path in each_paths)):
        try:
            check_image_output(path, size)
        except PanomapError as exc:
            raise usage_error(exc, option) from None
    if getattr(view, "distance", None) is not None and view.kind in DISTANCE_KINDS and _at_one_point(rig):
        say_note("--distance changes nothing here: the rig's cameras sit at one point (a camchain's t of 0); "
                 "give their separation in its calibration")  # fmt: skip
    pictures = _pictures(rig, rig_path, images)
    images_bytes = max(image_file_bytes(size, picture) for picture in pictures)
    check_room([*map_file_bytes(size, save_map_path), *((path, images_bytes) for path in (output, *each_paths))],
               up_to=True)  # fmt: skip
    maps = camera_maps(rig, view, sampling)
    remapper = RigRemapper(rig, maps, interp, wrap=view.kind in WRAPPING_KINDS)
    layers = remapper.layers(pictures)  # (made once: the gains, the blend and --each read them)
    gains = remapper.layer_gains(layers)
    blended = remapper.blend(layers, gains)
    with all_or_none():
        write_image(output, blended)
        if save_map_path is not None:
            save_map(save_map_path, _strongest_map(maps, remapper.weights))
        if each is not None:
            for path, layer in zip(each_paths, layers, strict=True):
                write_image(path, layer)
    seen = float(np.mean(remapper.weights.sum(axis=0) > 0))
    shared = float(np.mean((remapper.weights > 0).sum(axis=0) > 1))
    shown = ", ".join(f"{name} x{float(np.mean(g)):.3f}" for name, g in zip(rig.names, gains, strict=True))
    mixed = f", {_percent(shared)} blended from two cameras or more" if rig.count > 1 else ""
    say(
        f"wrote {printable(str(output))} ({blended.shape[1]} x {blended.shape[0]}: {_percent(seen)} seen{mixed}; "
        f"gains {shown})"
    )
    if each_paths:
        say(f"wrote each camera's own view: {', '.join(printable(str(path)) for path in each_paths)}")


def _percent(fraction: float) -> str:
    """A share of the view's pixels, as a percentage that says 'all' or 'none' only when it is."""
    if 0.0 < fraction < 0.01:
        return "under 1%"
    if 0.99 < fraction < 1.0:
        return f"{fraction:.1%}"
    return f"{fraction:.0%}"


def _at_one_point(rig: CameraRig) -> bool:
    """Whether every camera of ``rig`` sits at camera 0's position (world units, within 1e-9 of it)."""
    positions = np.array([table.camera_position for table in rig.tables], dtype=np.float64)
    return bool(np.all(np.abs(positions - positions[0]) <= 1e-9 * max(1.0, float(np.abs(positions).max()))))


def _pictures(rig: CameraRig, rig_path: Path, images: tuple[Path, ...]) -> list[Any]:
    """The rig's pictures: one frame holding them all, or one per camera in the rig's order (sizes checked)."""
    try:
        return read_rig_pictures(rig, images)
    except PanomapError as exc:
        if exc.source is None:  # (a wrong number of pictures: the command line's fault)
            raise click.UsageError(exc.detail) from None
        for image in images:
            refuse_video_as_picture(exc, rig_path, image)
        raise


def _strongest_map(maps: list[Any], weights: Any) -> Any:
    """One (H, W, 2) map: each pixel's source in the camera that counts most there (its own picture's pixels)."""
    strongest = np.argmax(weights, axis=0)
    out = np.full_like(maps[0], np.nan)
    for k, map_uv in enumerate(maps):
        mine = strongest == k
        out[mine] = map_uv[mine]
    out[weights.sum(axis=0) == 0] = np.nan
    return out


def _write_rig(rig: CameraRig, output: Path, report: Iterable[str]) -> None:
    """Writes ``rig`` to ``output`` whole or not at all, then prints ``report`` (what the command found) and the
    file written."""
    with all_or_none():
        save_rig(rig, output)
    for line in report:
        for piece in fold_line(printable(line)):
            say(piece)
    say(f"wrote {printable(str(output))}")


REPORT_WIDTH = 160
"""A report line's characters at most, where it can be cut (after a '; ')."""


def fold_line(line: str, width: int = REPORT_WIDTH) -> list[str]:
    """``line`` cut after its '; ' where it runs past ``width`` characters, each further piece indented two spaces
    more than the line (a piece with no '; ' in it stays whole, however long)."""
    indent = " " * (len(line) - len(line.lstrip(" ")) + 2)
    pieces = line.split("; ")
    out = [pieces[0]]
    for piece in pieces[1:]:
        if len(out[-1]) + 2 + len(piece) <= width:
            out[-1] += "; " + piece
        else:
            out[-1] += ";"
            out.append(indent + piece)
    return out


def rig_format(path: Path, format_: str | None) -> str | None:
    """The format of ``path`` where it holds a rig (a Kalibr camchain of two or more cameras each with its
    T_cn_cnm1, a Basalt calibration of two or more cameras with their T_imu_cam, a Hugin project of two or more
    images); None otherwise (the single camera's import says what is wrong with a file it cannot read).

    Raises
    ------
    PanomapError
        Where the file writes a rig (several cameras, poses between them) and one of them is malformed (a pose
        of NaN, a camera without its pose): imported as one camera, camera 0 alone came out of a rig, silently.
    """
    from ..interop.readers import READERS, basalt, hugin_pto, kalibr

    try:
        text = read_text(path)
    except PanomapError:
        return None
    found = [name for name, entry in READERS.items() if entry.looks_like(text)] if format_ is None else [format_]
    if not found or found[0] not in ("kalibr", "basalt", "hugin"):
        return None
    # A file naming one camera is no rig: it is not parsed here (the import parses it once).
    if found[0] == "kalibr":
        many = len(kalibr.CAMERA_MODEL_KEY.findall(text)) > 1
        try:
            count = len(kalibr.read_chain(text, path)) if many else 1
        except PanomapError:
            if "T_cn_cnm1" in text:
                raise
            return None  # (cameras without poses: no chain; the import takes the first, as documented)
    elif found[0] == "basalt":
        count = len(basalt.read(text, path, None).rig_poses) if text.count('"camera_type"') > 1 else 1
    else:
        try:
            count = len(hugin_pto.read_images(text, path))
        except PanomapError:
            return None  # (a project whose images cannot be read: the single camera's import says why)
    return found[0] if count > 1 else None


def _cameras(path: Path, format_: str) -> tuple[list[Any], Any]:
    """The rig's cameras (:class:`panomap.interop.rig_of_models.RigCamera`) and camera 0's axes where the file
    gives them (Hugin's; None otherwise)."""
    if format_ == "kalibr":
        from ..interop.rig_of_camchain import camchain_cameras

        return camchain_cameras(path), None
    if format_ == "basalt":
        from ..interop.rig_of_basalt import basalt_cameras

        return basalt_cameras(path), None
    from ..interop.rig_of_pto import pto_cameras

    return pto_cameras(path)


def import_rig(
    calibration: Path,
    format_: str,
    output: Path,
    *,
    orientation: tuple[float, float, float] | None,
    camera: tuple[float, float, float],
    side_by_side: bool,
    fov_deg: float | None,
    images: tuple[Path, ...],
    table_size: tuple[int, int] | None,
    find_circles: Callable[[Path, Any], Any],
) -> None:
    """``panomap import`` of a file of several cameras: the rig's file. With pictures of a camchain's rig, its
    poses are checked against them (:mod:`panomap.rig.check`): one that looks inverted is refused."""
    from ..interop.rig_of_models import axes_of_orientation, rig_of_models

    if format_ == "hugin" and orientation is not None:
        raise click.UsageError(
            "a Hugin project's cameras look as its yaw, pitch and roll say: --orientation does not apply"
        )
    cameras, axes0 = _cameras(calibration, format_)
    orientation_rad = tuple(math.radians(a) for a in (orientation or (0.0, 0.0, 0.0)))
    if axes0 is None:
        axes0 = axes_of_orientation(orientation_rad)  # type: ignore[arg-type]
    outer_radii = None
    pictures = None
    if images:
        pictures = _rig_pictures(cameras, images, side_by_side)
        outer_radii = _circles_of_pictures(cameras, images, pictures, side_by_side, find_circles)
    fov_rad = None if fov_deg is None else math.radians(fov_deg)
    rig = rig_of_models(cameras, calibration, format_, axes0=axes0, centre0=camera, side_by_side=side_by_side,
                        size=table_size, fov_rad=fov_rad, outer_radii=outer_radii)  # fmt: skip
    if pictures is not None and format_ == "kalibr":
        _check_poses(calibration, pictures, orientation_rad, side_by_side, fov_rad, outer_radii)  # type: ignore[arg-type]
    _write_rig(rig, output, rig.describe())


def _check_poses(
    calibration: Path,
    pictures: list[Any],
    orientation_rad: tuple[float, float, float],
    side_by_side: bool,
    fov_rad: float | None,
    outer_radii: tuple[float | None, ...] | None,
) -> None:
    """Refuse a camchain whose pictures agree clearly better with one camera's pose inverted."""
    from ..interop.rig_of_camchain import check_camchain_pictures

    comparison = check_camchain_pictures(
        calibration,
        pictures,
        orientation_rad=orientation_rad,
        side_by_side=side_by_side,
        fov_rad=fov_rad,
        outer_radii=outer_radii,
    )
    given = comparison.given
    shown = f"{given.score:.2f}" if math.isfinite(given.score) else "no overlap"
    say(f"the cameras' overlaps agree at {shown} in the pictures (zero-normalised cross-correlation)")
    if comparison.suspect is None:
        return
    name = comparison.suspect
    flipped = comparison.alternatives[name]
    names = list(_names_of(calibration))
    k = names.index(name)
    # The pair of that camera whose agreement the inversion improves most (a pair not overlapping as given: -1).
    mine = [(pair, value) for pair, (value, _) in flipped.pairs.items() if k in pair]
    if not mine:
        where = f"the overlaps agree at {flipped.score:.2f} inverted, {shown} as given"
    else:
        (i, j), value = max(mine, key=lambda item: item[1] - given.pairs.get(item[0], (-1.0, 0))[0])
        before = given.pairs.get((i, j))
        as_given = f"{before[0]:.2f}" if before is not None else "no overlap"
        where = f"its overlap with {names[j if i == k else i]} agrees at {value:.2f} inverted, {as_given} as given"
    raise PanomapError(
        f"{name}'s T_cn_cnm1 looks inverted or transposed (its rotation the other way round): {where}", calibration
    )


def _names_of(calibration: Path) -> list[str]:
    from ..interop.rig_of_camchain import camchain_cameras

    return [camera.name for camera in camchain_cameras(calibration)]


def _rig_pictures(cameras: list[Any], images: tuple[Path, ...], side_by_side: bool) -> list[Any]:
    """The pictures of the rig: one frame holding them side by side, or one per camera (sizes checked)."""
    sizes = [camera.imported.image_size for camera in cameras]
    if side_by_side:
        if len(images) != 1:
            raise click.UsageError(
                f"--side-by-side: give the one frame holding the cameras, not {len(images)} pictures"
            )
        frame_size = (sum(w for w, _ in sizes), max(h for _, h in sizes))
        return [read_omni(images[0], None, frame_size, "the rig's frame")]
    if len(images) != len(cameras):
        names = ", ".join(camera.name for camera in cameras)
        raise click.UsageError(f"--image: give one picture per camera ({names}), or one frame with --side-by-side")
    return [read_omni(image, None, size, f"camera {camera.name}") for image, size, camera in
            zip(images, sizes, cameras, strict=True)]  # fmt: skip


def _circles_of_pictures(
    cameras: list[Any],
    images: tuple[Path, ...],
    pictures: list[Any],
    side_by_side: bool,
    find_circles: Callable[[Path, Any], Any],
) -> tuple[float | None, ...]:
    """Each camera's image circle (px about its principal point) found in its picture (its part of the one frame),
    where found; None where not."""
    radii: list[float | None] = []
    x = 0
    for k, camera in enumerate(cameras):
        width, height = camera.imported.image_size
        if side_by_side:
            part, image = np.ascontiguousarray(pictures[0][:height, x : x + width]), images[0]
            x += width
        else:
            part, image = pictures[k], images[k]
        try:
            circles = find_circles(image, part)
        except PanomapError as exc:
            say_note(f"{printable(str(exc))}; its table stops at the model's range")
            radii.append(None)
            continue
        u0, v0 = camera.imported.model.principal_point
        offset = math.hypot(circles.centre[0] - u0, circles.centre[1] - v0)
        radii.append(circles.outer.radius - offset if circles.rim_seen > 0.25 else None)
    return tuple(radii)


def describe_rig_file(path: Path, as_json: bool) -> None:
    """``panomap info`` of a rig file: its cameras, where each sits and looks, what each sees, the overlaps (or
    every camera's table metadata as JSON)."""
    import json

    rig = load_rig(path)
    if as_json:
        cameras = [{"name": name} | table.metadata() for name, table in zip(rig.names, rig.tables, strict=True)]
        click.echo(json.dumps({"format": "panomap-rig", "offsets": rig.offsets, "info": rig.info, "cameras": cameras},
                              indent=2))  # fmt: skip
        return
    click.echo(printable("\n".join([f"{path}: panomap rig", *rig.describe()]), keep="\n"))


@click.group("rig")
def rig() -> None:
    """A rig of cameras: make one of their tables, learn its rotations from pictures, place it from floor landmarks.

    \b
      panomap rig make front.npz back.npz -o theta.npz
      panomap rig learn theta.npz front.jpg back.jpg -o learned.npz
      panomap rig place car.npz front.csv left.csv back.csv right.csv -o placed.npz
    """


@rig.command("make")
@click.argument("tables", type=click.Path(exists=True, dir_okay=False, path_type=Path), nargs=-1, required=True)
@click.option(
    "-o", "--output", type=click.Path(dir_okay=False, path_type=Path), required=True, help="Rig file to write (.npz)."
)
@click.option("--name", "names", multiple=True, help="Each camera's name, in order [default: each table's file name].")
@click.option(
    "--side-by-side", is_flag=True, help="Their pictures come side by side in one frame, camera 0 on the left."
)
def rig_make(tables: tuple[Path, ...], output: Path, names: tuple[str, ...], side_by_side: bool) -> None:
    """A rig of TABLES (each camera's table, placed in one world: import --orientation --camera)."""
    from ..table.file import load_table

    if names and len(names) != len(tables):
        raise click.BadParameter(f"{len(names)} names for {len(tables)} tables", param_hint="'--name'")
    if len(tables) > MAX_CAMERAS:  # (before loading them)
        raise click.BadParameter(f"a rig has 1 to {MAX_CAMERAS} cameras, not {len(tables)}", param_hint="'TABLES...'")
    check_table_outputs([("a table", table) for table in tables], output, "a rig")
    loaded = tuple(load_table(table) for table in tables)
    offsets = None
    if side_by_side:
        x, placed = 0, []
        for table in loaded:
            placed.append((x, 0))
            x += table.image_size[0]  # type: ignore[index]
        offsets = tuple(placed)
    try:
        made = CameraRig(
            loaded, names or tuple(table.stem for table in tables), offsets, {"made of": [t.name for t in tables]}
        )
    except PanomapError as exc:
        if names:
            raise
        # The names were the tables' file names: say so, and how to give others.
        raise click.UsageError(
            f"{exc.detail}: the cameras are named after their tables' files; name each with --name"
        ) from None
    _write_rig(made, output, made.describe())


@rig.command("learn")
@click.argument(
    "paths",
    metavar="[RIG] PICTURE...",
    type=click.Path(exists=True, dir_okay=False, path_type=Path),
    nargs=-1,
    required=True,
)
@click.option(
    "-o", "--output", type=click.Path(dir_okay=False, path_type=Path), required=True, help="Rig file to write (.npz)."
)
@click.option(
    "--side-by-side",
    is_flag=True,
    help="No RIG: a dual fisheye's frames alone (each lens side by side, lens 0 on the left): each lens is learned "
    "from its lines too, and refused where the frames cannot pin it.",
)
@click.option(
    "-v", "--verbose", is_flag=True, help="Where it is refused: the figures behind the refusal after its line."
)
def rig_learn(paths: tuple[Path, ...], output: Path, side_by_side: bool, verbose: bool) -> None:
    """The rotations between RIG's cameras, learned from the features they share in its PICTUREs (each a frame
    holding every camera's picture, or one picture per camera in the rig's order, shot after shot); camera 0
    stays where it is. The rig must be placed within a few degrees (a dual fisheye's lenses back to back). For two
    cameras, their overlap's tiles then say whether camera 1's centre must move (kept only where it predicts
    left-out parts of the overlap clearly better; the report's last line says which).

    With --side-by-side and no RIG, a dual fisheye with no calibration at all: its lenses and the turn between
    them from its side-by-side frames alone (panomap rig learn --side-by-side FRAME... -o rig.npz)."""
    if side_by_side:
        _learn_dual(paths, output, verbose)
        return
    if len(paths) < 2:
        raise click.UsageError(
            "give the rig and its pictures (or, with no rig, --side-by-side and a dual fisheye's frames)"
        )
    _learn_rig(paths[0], paths[1:], output)


def _learn_rig(rig_path: Path, images: tuple[Path, ...], output: Path) -> None:
    """``rig learn RIG PICTURE...``: the rotations of a rig whose lenses are known."""
    from ..interop.orient import turn_table
    from ..rig.overlap import learn_with_overlap

    loaded = load_rig(rig_path)
    check_table_outputs([("the rig", rig_path), *(("a picture", image) for image in images)], output, "a rig")
    check_room_as(output, rig_path)
    per_shot = 1 if loaded.offsets is not None else loaded.count
    if len(images) % per_shot:
        names = ", ".join(loaded.names)
        raise click.UsageError(f"give one picture per camera of the rig ({names}), shot after shot, not {len(images)}")
    if per_shot == 1:  # (a shot's cameras' pictures given twice: _refuse_same_shot, below)
        refuse_same_input(images, "picture", "its matches twice would count twice", lambda _: "'PICTURES...'")
    shots: list[Any] = []
    for start in range(0, len(images), per_shot):
        pictures = read_rig_pictures(loaded, images[start : start + per_shot], read=_read_omni)
        _refuse_same_shot(shots, pictures, images[start : start + per_shot], per_shot)
        shots.append(pictures[0] if loaded.offsets is not None else pictures)
    learned = learn_with_overlap(loaded, shots, turn=turn_table)
    _write_rig(learned.rig, output, learned.describe())


def _refuse_same_shot(shots: list[Any], pictures: list[Any], paths: tuple[Path, ...], per_shot: int) -> None:
    """Refuse a shot whose pictures hold the same pixels as an earlier shot's (a copy saved again): its matches
    would count twice, and the tilt's bound would narrow as if a second view had pinned it."""
    for number, shot in enumerate(shots):
        earlier = [shot] if per_shot == 1 else shot
        if all(np.array_equal(a, b) for a, b in zip(earlier, pictures, strict=True)):
            raise PanomapError(
                f"the same pixels as shot {number + 1}: give each shot once (its matches twice would count twice)",
                paths[0],
            )


def _read_omni(path: Path, size: tuple[int, int] | None, expected_by: str) -> Any:
    """A rig's picture as :func:`read_omni` reads it: a video's first frame, with a note."""
    return read_omni(path, None, size, expected_by)


def _learn_dual(frames: tuple[Path, ...], output: Path, verbose: bool) -> None:
    """``rig learn --side-by-side FRAME...``: a dual fisheye's lenses and their turn from its frames alone
    (:func:`panomap.calibrate.dual_fisheye.learn_dual_fisheye`); a refusal's figures with ``verbose``."""
    from ..calibrate.dual_fisheye import learn_dual_fisheye, split_frame

    if any(is_rig_file(path) for path in frames):
        raise click.UsageError(
            "--side-by-side learns the lenses too, from the frames alone: give no rig (or drop --side-by-side)"
        )
    check_table_outputs([("a frame", frame) for frame in frames], output, "a rig")
    refuse_same_input(frames, "frame", "its lines twice add nothing", lambda _: "'PICTURE...'")
    pictures = [read_omni(frame) for frame in frames]
    for frame, picture in zip(frames, pictures, strict=True):
        try:
            split_frame(picture)
        except PanomapError as exc:
            raise PanomapError(exc.detail, frame) from None
    bar = progress_bar("step")
    try:
        learned = learn_dual_fisheye(pictures, progress=bar.stage)
    except PanomapError as exc:
        error = PanomapError(exc.detail, exc.source)
        error.verbose = verbose  # type: ignore[attr-defined]
        raise error from None
    finally:
        bar.close()
    _write_rig(learned.rig, output, learned.describe())


@rig.command("place")
@click.argument("rig_path", metavar="RIG", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.argument(
    "landmark_files",
    metavar="LANDMARKS...",
    type=click.Path(exists=True, dir_okay=False, path_type=Path),
    nargs=-1,
    required=True,
)
@click.option(
    "-o", "--output", type=click.Path(dir_okay=False, path_type=Path), required=True, help="Rig file to write (.npz)."
)
@click.option(
    "--unit",
    type=click.Choice(["m", "cm", "mm"]),
    default=None,
    help="The landmarks' world unit: the floor's residuals are then printed in cm [default: in world units].",
)
def rig_place(rig_path: Path, landmark_files: tuple[Path, ...], output: Path, unit: str | None) -> None:
    """Every camera of RIG placed in one world from its floor LANDMARKS (one file per camera, in the rig's order:
    a CSV of u,v,X,Y,Z rows with Z = 0, or JSON, as `panomap fit` reads them; every camera's X, Y in the same
    world, Z up, from one tape measure). Each camera's lens stays as it is; its rotation and position are
    replaced. Prints each camera's residuals (px, and on the floor)."""
    from ..calibrate.landmarks.pairs import read_landmarks
    from ..interop.orient import turn_table
    from ..rig.place import place_on_floor

    loaded = load_rig(rig_path)
    check_table_outputs([("the rig", rig_path), *(("landmarks", path) for path in landmark_files)], output, "a rig")
    check_room_as(output, rig_path)
    if len(landmark_files) != loaded.count:
        names = ", ".join(loaded.names)
        raise click.UsageError(f"give one landmark file per camera of the rig, in its order ({names}), not "
                               f"{len(landmark_files)}")  # fmt: skip
    landmarks = []
    for path in landmark_files:
        read = read_landmarks(path)
        landmarks.append((read.pixels, read.world))
    try:
        placed = place_on_floor(loaded, landmarks, turn=lambda t, r: turn_table(t, r, "placed from floor landmarks"))
    except PanomapError as exc:
        # The camera the refusal names is the file's: say which file.
        named = next((k for k, name in enumerate(loaded.names) if exc.detail.startswith(f"camera {name}:")), None)
        raise PanomapError(exc.detail, landmark_files[named] if named is not None else None) from None
    _write_rig(placed.rig, output, placed.describe(unit))
