"""``panomap batch``: many images and videos, of one camera or several, unwarped on Dask.

The command line edge of :mod:`panomap.batch`.
"""

from __future__ import annotations

import sys
import threading
from pathlib import Path

import click

from ..batch.forkserver import SCHEDULER_VARIABLE
from ..batch.job import (
    TEMPLATE_KEYS,
    BatchInput,
    Settings,
    check_inputs_and_table,
    check_template,
    check_video_views,
    find_inputs,
    make_job,
    without_outputs,
)
from ..batch.record import Record
from ..batch.run import Progress, RunSettings, run_job
from ..errors import PanomapError, printable
from ..remap import INTERPOLATIONS
from ..table.sampling import SAMPLINGS
from ..video.output import EncoderSettings
from ..views.spec import KINDS, NamedView
from .options import PATH, Finite, usage_error, warn_orientation
from .options import quiet as quiet_given
from .progress import ProgressBar
from .video import encoder_settings, stop_on_signals, views_of


class _Bar(ProgressBar):
    """The job's bar: frames, fps, ETA, and the inputs done as its postfix."""

    def __call__(self, progress: Progress) -> None:
        inputs = f"{progress.inputs_done}/{progress.inputs_total} inputs"
        self.update(progress.frames_done, progress.frames_total, inputs)


@click.command()
@click.argument("inputs", nargs=-1, required=True, metavar="INPUT...")
@click.option(
    "-o",
    "--output",
    "template",
    required=True,
    metavar="TEMPLATE",
    help="Output path per input and view, with " + ", ".join(f"{{{k}}}" for k in TEMPLATE_KEYS) + " "
    "(e.g. '{camera}/{stem}_{name}.mp4'); still images keep their own format.",
)
@click.option(
    "--table",
    type=PATH,
    help="The table of every input (without a manifest), or a rig file: each input its one side-by-side frame "
    "or video, or a folder of one picture or video per camera.",
)
@click.option(
    "--exclude",
    "excludes",
    multiple=True,
    metavar="GLOB",
    help="Leave out the inputs that match GLOB by name or path ('*' crosses folders), e.g. "
    "--exclude '*/old/*' --exclude '*.avi'; repeatable. The job's own outputs are always left out.",
)
@click.option("--camera", help="The camera's name for {camera} (without a manifest; default: the table's stem).")
@click.option(
    "--view",
    "specs",
    multiple=True,
    metavar="SPEC",
    help="A view, KIND:key=value,... with KIND one of " + ", ".join(KINDS) + " (as panomap video). Repeatable.",
)
@click.option("--views", "views_file", type=PATH, help="A JSON or YAML file of named views (as panomap video).")
@click.option(
    "--record",
    "record_path",
    type=PATH,
    default=Path("panomap-batch.jsonl"),
    show_default=True,
    help="The JSON-lines record of finished outputs: a rerun skips what it holds as complete.",
)
@click.option("--force", is_flag=True, help="Redo every output, complete or not.")
@click.option(
    "--scheduler",
    metavar="ADDRESS",
    help=f"A Dask scheduler (tcp://host:8786) to run on; default ${SCHEDULER_VARIABLE}, else a local cluster.",
)
@click.option("--workers", type=click.IntRange(min=1), help="Worker processes of the local cluster (default: cores).")
@click.option(
    "--segment",
    "segment_s",
    type=Finite(1.0),
    metavar="SECONDS",
    help="Split videos longer than this into segments of this length (1 s or more), unwarped in parallel and joined.",
)
@click.option("--chunk", type=click.IntRange(min=1), help="Still images per task (default: about 4 tasks per worker).")
@click.option("--retries", type=click.IntRange(min=0), default=2, show_default=True, help="Retries of a failing input.")
@click.option("--codec", default="libx264", show_default=True, help="Video encoder (FFmpeg name).")
@click.option("--pix-fmt", default="yuv420p", show_default=True, help="Encoded pixel format.")
@click.option("--crf", type=click.IntRange(0, 63), default=20, show_default=True, help="Quality (x264/x265).")
@click.option("--preset", default="veryfast", show_default=True, help="Speed preset (x264/x265).")
@click.option("--bitrate", help="Target bit rate instead of --crf, e.g. 8M.")
@click.option(
    "--encoder-option", "encoder_options", multiple=True, metavar="KEY=VALUE", help="More encoder options. Repeatable."
)
@click.option("--no-audio", is_flag=True, help="Do not copy the videos' audio.")
@click.option("--interp", type=click.Choice(list(INTERPOLATIONS)), default="linear", show_default=True)
@click.option("--table-sampling", type=click.Choice(SAMPLINGS), default="bilinear", show_default=True)
def batch(
    inputs: tuple[str, ...],
    template: str,
    table: Path | None,
    excludes: tuple[str, ...],
    camera: str | None,
    specs: tuple[str, ...],
    views_file: Path | None,
    record_path: Path,
    force: bool,
    scheduler: str | None,
    workers: int | None,
    segment_s: float | None,
    chunk: int | None,
    retries: int,
    codec: str,
    pix_fmt: str,
    crf: int,
    preset: str,
    bitrate: str | None,
    encoder_options: tuple[str, ...],
    no_audio: bool,
    interp: str,
    table_sampling: str,
) -> None:
    """Unwarp many images and videos (one camera or several) into views, on Dask.

    INPUT is a file, a folder (every image and video in it), a glob ('cams/**/*.jpg'), or
    one manifest (.csv, .json, .yaml) mapping each input to its camera's table:

    \b
      input,table,camera
      north/0001.jpg,north.npz,north
      south/day1.mp4,south.npz,south

    A table may be a rig file (panomap import of several cameras): each input is then the
    frame (or video) holding its cameras side by side, or a folder holding one picture (or
    video) per camera, named after the cameras or in the rig's order by name.

    The job runs on a local Dask cluster (one worker per core) unless --scheduler (or
    DASK_SCHEDULER_ADDRESS) names an existing one, whose workers must see the same paths.
    Every finished output is recorded (--record); run the same command again to finish an
    interrupted or failed job: complete outputs are skipped. A failing input is retried,
    then reported, and the rest goes on; the exit code is 1 if any input failed.

    \b
    Example:
      panomap batch cams.csv -o 'out/{camera}/{stem}_{name}.mp4' \\
          --view panorama:size=2048x512 --view perspective:yaw=30,pitch=-20,fov=90,size=1280x720,name=door
    """
    quiet = quiet_given()
    named = views_of(specs, views_file)
    encoder = encoder_settings(codec, pix_fmt, crf, preset, bitrate, encoder_options)
    try:
        check_template(template)
    except PanomapError as exc:
        raise usage_error(exc, "-o") from None
    try:
        manifest = check_inputs_and_table(inputs, table)
    except PanomapError as exc:
        raise usage_error(exc) from None
    if manifest is not None and camera is not None:
        raise click.BadParameter(
            f"{printable(str(manifest))} names each input's camera (or takes its table's stem): give no --camera",
            param_hint="'--camera'",
        )
    found, outputs = without_outputs(find_inputs(inputs, table, camera, excludes), named, template)
    if outputs and not quiet:
        click.echo(
            f"panomap batch: note: {len(outputs)} of the files found are outputs of this job (under {template}): "
            "left out",
            err=True,
        )
    if not found:
        raise PanomapError("every input found is an output of this job: name the inputs, not the outputs' folder")
    # Each camera's first still image, as the views do: an EXIF orientation asks viewers to turn it (its views
    # are of the pixels as stored, as the table is); once a camera, not once an image.
    for first in {item.camera: item for item in reversed(found) if not item.is_video}.values():
        warn_orientation(first.sources[0])
    if any(item.is_video for item in found):
        _check_encoder(found, named, encoder)
    if interp not in ("linear", "nearest") and any(item.rig and item.is_video for item in found):
        raise click.BadParameter(f"a rig's video reads linear or nearest, not {interp!r}", param_hint="'--interp'")
    job = make_job(found, named, template, Settings(encoder, interp, table_sampling, not no_audio))
    record = Record(record_path)
    stop = threading.Event()
    bar = _Bar(not quiet and sys.stderr.isatty())
    try:
        with stop_on_signals(stop):
            report = run_job(
                job,
                record,
                RunSettings(scheduler, workers, force, retries, segment_s, chunk),
                progress=bar,
                stop=stop,
                warn=lambda message: bar.write(f"panomap batch: {message}"),
                on_dashboard=None if quiet else lambda link: bar.write(f"Dask dashboard: {link}"),
            )
    finally:
        bar.close()
    if not quiet:
        fps = report.frames / report.seconds if report.seconds > 0 else 0.0
        skipped = f", {report.skipped} already complete" if report.skipped else ""
        click.echo(
            f"unwarped {report.done} of {report.inputs} inputs ({report.outputs} outputs, {report.frames} frames) "
            f"in {report.seconds:.1f} s ({fps:.1f} frames/s) on {report.workers} worker(s){skipped}; "
            f"record: {record.path}"
        )
    if report.failed:
        raise PanomapError(
            f"{len(report.failed)} of {report.inputs} inputs failed (listed above, and in the record "
            f"{record.path}); run the same command again to retry them"
        )
    if report.interrupted:
        click.echo(
            f"panomap batch: interrupted: run the same command again to finish ({record.path} holds what is done)",
            err=True,
        )
        sys.exit(130)


def _check_encoder(found: list[BatchInput], named: list[NamedView], encoder: EncoderSettings) -> None:
    """The video encoder's options and the views' sizes, refused once before the cluster (usage errors)."""
    try:
        encoder.check()
    except PanomapError as exc:
        raise usage_error(exc) from None
    try:
        check_video_views(found, named, encoder)
    except PanomapError as exc:
        raise usage_error(exc, "--view") from None
