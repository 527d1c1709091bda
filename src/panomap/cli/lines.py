"""``panomap fit --image IMG [--image IMG ...]`` without landmarks: the camera learned from straight lines."""

from __future__ import annotations

import time
from pathlib import Path

import click
import numpy as np

from ..calibrate.circles import ImageCircles
from ..calibrate.lines.fit import LineFitOptions
from ..calibrate.pictures import NotLearned, learn_from_images
from ..errors import PanomapError, printable
from ..files import all_or_none
from ..io.images import write_image
from ..table.file import save_table
from ..table.table import PanoMappingTable
from .options import progress_bar, quiet, read_omni, say, say_note, warn_orientation, warn_rotation
from .progress import ProgressBar


def fit_from_lines(
    images: tuple[Path, ...],
    output: Path,
    *,
    frame_time: float | None,
    options: LineFitOptions,
    camera_height: float | None,
    overlay: Path | None,
    use_boards: bool = True,
    videos: tuple[Path, ...] = (),
    video_frames: int = 8,
    uncertainty_plot: Path | None = None,
) -> None:
    """Learn the camera from the lines of ``images`` and of ``video_frames`` frames of each of ``videos`` (those
    that show a view no earlier picture shows), write its table (and ``overlay``, and the projection uncertainty
    figure ``uncertainty_plot`` of a camera learned from checkerboards), say what the fit saw.

    Checkerboards in the images (``use_boards``) and the edge arcs both count
    (:func:`panomap.calibrate.pictures.learn_from_images`, which does the work): a board's corners are evenly
    spaced on straight lines at right angles, which fixes the scale that straightness alone leaves loose; with
    few boards the line fit is made too and the camera that explains both is kept.
    """
    started = time.monotonic()
    limit = _check_memory(images, videos)
    bar = progress_bar("step")
    try:
        bar.stage(f"reading {len(images)} picture{'s' if len(images) != 1 else ''}")
        omnis = _read_all(images, frame_time)
        names: list[str | Path] = list(images)
        if videos:
            omnis, names = _with_frames(omnis, names, videos, video_frames, bar, limit)
        try:
            learned = learn_from_images(
                omnis,
                names=names,
                camera_height=camera_height,
                model=options.model,
                axis=options.axis,
                handedness=options.s,
                azimuth_zero=options.azimuth_zero,
                boards=use_boards,
                progress=bar.update,
            )
        except NotLearned as exc:
            if overlay is not None:  # what the pictures gave, so the user sees which lines were found
                from ..io.line_overlay import draw_found_overlay

                bar.close()
                write_image(overlay, draw_found_overlay(omnis[0], exc.arcs, exc.circles, exc.detail.split("\n")[0]))
                say(f"wrote {overlay} (the edges found; no camera)")
            raise
        table = learned.table
        if uncertainty_plot is not None:
            _check_band(table)
        bar.stage("writing the table" + (" and its pictures" if overlay or uncertainty_plot else ""))
        with all_or_none():
            save_table(table, output)
            if overlay is not None:
                from ..io.line_overlay import draw_line_overlay

                write_image(overlay, draw_line_overlay(omnis[0], table, learned.arcs))
            if uncertainty_plot is not None:
                from ..io.uncertainty_plot import save_uncertainty_plot

                save_uncertainty_plot(table, uncertainty_plot, output)
    finally:
        bar.close()
    say(printable(describe_line_fit(table, learned.circles, time.monotonic() - started), keep="\n"))
    if learned.choice is not None:
        say(learned.choice)
    written = [str(path) for path in (output, overlay, uncertainty_plot) if path is not None]
    say("wrote " + (", ".join(written[:-1]) + " and " + written[-1] if len(written) > 1 else written[0]))
    for warning in learned.warnings:
        click.echo(f"panomap: warning: {printable(warning)}", err=True)  # (they name the pictures)


def _check_band(table: PanoMappingTable) -> None:
    """Refuse ``--uncertainty-plot`` before anything is written where the camera kept is not the boards'."""
    from ..io.uncertainty_plot import table_projection_band

    try:
        table_projection_band(table)
    except PanomapError:
        raise PanomapError(
            "--uncertainty-plot draws a camera learned from checkerboards; the pictures' lines gave this one (no "
            "board kept): leave it out"
        ) from None


def _with_frames(
    omnis: list[np.ndarray],
    names: list[str | Path],
    videos: tuple[Path, ...],
    count: int,
    bar: ProgressBar,
    limit: int | None,
) -> tuple[list[np.ndarray], list[str | Path]]:
    """The pictures and their names, with up to ``count`` frames of each video (:func:`panomap.video.sample.each_frame`)
    after them, less those that show a view an earlier picture shows (:mod:`panomap.calibrate.core.distinct`),
    saying on stderr what was taken.

    The frames are decoded one at a time and one showing a view already seen is dropped at once; a video takes
    only as many frames as the line search's memory (:mod:`panomap.calibrate.lines.budget`) leaves room for
    within ``limit`` bytes, from its header's frame size before any is decoded, saying so where that is fewer
    than ``count``.
    """
    from ..calibrate.core.distinct import DistinctViews
    from ..calibrate.lines.budget import BYTES_PER_IMAGE_PIXEL, line_search_memory
    from ..io.images import MAX_IMAGE_PIXELS
    from ..video.sample import each_frame, frame_size

    pictures, labels, views = [], [], DistinctViews()
    for picture, label in zip(omnis, names, strict=True):
        if views.add(picture):
            pictures.append(picture)
            labels.append(label)
    for video in videos:
        bar.stage(f"taking up to {count} frames of {video.name}")
        width, height = frame_size(video)
        room = count
        if limit is not None:
            spare = limit - line_search_memory([(p.shape[1], p.shape[0]) for p in pictures])
            room = min(count, max(spare, 0) // (BYTES_PER_IMAGE_PIXEL * width * height))
            if room < count:
                _say_fewer(video, room, count, (width, height), limit)
        taken = kept = 0
        for at_s, frame in each_frame(video, count, MAX_IMAGE_PIXELS) if room else ():
            taken += 1
            if views.add(frame):
                pictures.append(frame)
                labels.append(f"{video} at {at_s:.2f} s")
                kept += 1
                if kept == room:
                    break
        warn_rotation(video)
        if not quiet():
            bar.write(
                f"panomap: note: {printable(str(video))}: {taken} frames taken, {kept} showing a view no earlier "
                "picture shows (the others' lines would count twice)"
            )
    return pictures, labels


def _say_fewer(video: Path, room: int, count: int, size: tuple[int, int], limit: int) -> None:
    """The note (or, where not one frame fits, the refusal) for a video whose ``count`` frames of ``size`` would
    need more than ``limit`` bytes to learn from."""
    from ..calibrate.lines.budget import line_search_memory

    needed = line_search_memory([size] * count) / 1e9
    width, height = size
    if room == 0:
        raise PanomapError(
            f"learning from a frame of {width} x {height} needs more memory than is left of the {limit / 1e9:.1f} GB "
            "available (3/4 of this machine's) after the other pictures: give fewer or smaller pictures",
            video,
        )
    say_note(
        f"{printable(str(video))}: learning from {count} frames of {width} x {height} would need "
        f"about {needed:.1f} GB of memory, more than the {limit / 1e9:.1f} GB available (3/4 of this machine's): "
        f"taking at most {room} frames showing distinct views"
    )


def _check_memory(images: tuple[Path, ...], videos: tuple[Path, ...] = ()) -> int | None:
    """The memory limit (bytes; None where unknown), after refusing, before reading any, images and one frame
    of each video whose line and board search needs more memory than there is (the sizes from the headers;
    an image whose header does not give it counts as none). ``_with_frames`` fits the videos' frames in."""
    from ..calibrate.lines.budget import check_line_search_memory
    from ..io.images import header_size
    from ..video.sample import frame_size
    from ..video.unwarp import machine_memory

    sizes = [size for size in (header_size(path) for path in images) if size is not None]
    sizes += [frame_size(video) for video in videos]
    total = machine_memory()
    limit = None if total is None else total * 3 // 4
    check_line_search_memory(sizes, limit)
    return limit


def _read_all(images: tuple[Path, ...], frame_time: float | None) -> list[np.ndarray]:
    """Every image (a video's frame at ``frame_time``), read and checked for its orientation (the sizes are
    checked by :func:`panomap.calibrate.pictures.learn_from_images`)."""
    omnis: list[np.ndarray] = []
    for path in images:
        omnis.append(read_omni(path, frame_time))
        warn_orientation(path)
    return omnis


def describe_line_fit(table: PanoMappingTable, circles: ImageCircles, seconds: float) -> str:
    """What the fit learned and saw, in a few lines."""
    from ..calibrate.core.report import table_fit_report

    report = table_fit_report(table)
    assert report is not None and report.lines is not None
    model = table.model
    tilt_deg, toward_deg = (float(np.degrees(a)) for a in model.tilt)
    out = [
        f"camera learned from {'checkerboards' if report.lines.boards else 'lines'} in {seconds:.1f} s: "
        f"radial model {report.model} "
        f"{tuple(round(c, 6) for c in model.radial.coefficients)}, centre ({model.centre[0]:.2f}, "
        f"{model.centre[1]:.2f}) (the rim's: ({circles.centre[0]:.2f}, {circles.centre[1]:.2f}))",
        f"tilt {tilt_deg:.2f} deg toward azimuth {toward_deg:.1f} deg"
        if report.lines.vertical_lines
        else "no vertical lines: the camera is taken as level"
        if not report.lines.boards
        else "",
        *(x for x in report.lines.sentences() if not x.startswith("no line between")),
        "azimuth 0 is "
        + ("the pixel given" if report.lines.azimuth_source == "given" else "image angle 0 (+u): --azimuth-zero U V")
        + f"; handedness s = {model.s:+d} ({report.lines.handedness_source}; --handedness to change)",
    ]
    if report.uncertainty is not None:
        out.append(f"standard error of the radius: at most {report.uncertainty.max_se_px:.2f} px")
    if not table.info.get("camera_height_known", True):
        out.append("distances unknown (lines know none): floor, cylinder and plane views need --camera-height H")
    return "\n".join(line for line in out if line)
