"""``panomap video``: unwarp a video file or live stream into one video per view.

The command line edge of :mod:`panomap.video`; view SPECs are parsed by
:mod:`panomap.views.spec`.
"""

from __future__ import annotations

import contextlib
import re
import signal
import sys
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import click

from ..errors import PanomapError
from ..files import check_outputs, fill_pattern, local_file, placeholders
from ..remap import INTERPOLATIONS
from ..rig.file import is_rig_file, load_rig
from ..table.file import load_table
from ..table.sampling import SAMPLINGS
from ..video.live import Reconnect
from ..video.output import EncoderSettings
from ..video.report import VideoReport
from ..video.rig import check_rig_sources, unwarp_rig_video
from ..video.source import Selection
from ..video.unwarp import ViewOutput, unwarp_video
from ..views.spec import KINDS, NamedView, name_views, parse_view_spec, read_views_file
from .options import FINITE, PATH, POSITIVE, quiet, rotation_warned, usage_error
from .progress import ProgressBar

# The highest bit rate taken (bit/s): FFmpeg holds it in a C long; 100 Gbit/s is past any encoder's.
MAX_BITRATE = 100 * 10**9


def _bitrate(text: str) -> int:
    match = re.fullmatch(r"\s*(\d+(?:\.\d+)?)\s*([kKmMgG]?)\s*", text)
    if not match:
        raise click.BadParameter(f"{text!r} is not a bit rate like 8M or 800k", param_hint="'--bitrate'")
    scale = {"": 1, "k": 10**3, "m": 10**6, "g": 10**9}[match.group(2).lower()]
    rate = float(match.group(1)) * scale
    if not 1 <= rate <= MAX_BITRATE:
        raise click.BadParameter(f"{text!r}: a bit rate is 1 to {MAX_BITRATE / 1e9:g}G bit/s", param_hint="'--bitrate'")
    return int(rate)


def views_of(specs: tuple[str, ...], views_file: Path | None) -> list[NamedView]:
    """The views of the --view SPECs (a SPEC that does not parse is a usage error) and the --views file."""
    parsed = []
    for spec in specs:
        try:
            parsed.append(parse_view_spec(spec))
        except PanomapError as exc:
            raise usage_error(exc, "--view") from None
    if views_file is not None:
        parsed += [(item.name, item.view) for item in read_views_file(views_file)]
    if not parsed:
        raise click.UsageError("give at least one --view SPEC or a --views file")
    return name_views(parsed)


def encoder_settings(
    codec: str, pix_fmt: str, crf: int, preset: str, bitrate: str | None, encoder_options: tuple[str, ...]
) -> EncoderSettings:
    """The encoder settings of the options (an option not KEY=VALUE is a usage error; checked by the caller)."""
    options = []
    for item in encoder_options:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise click.BadParameter(f"{item!r} is not KEY=VALUE", param_hint="--encoder-option")
        options.append((key, value))
    return EncoderSettings(
        codec, pix_fmt, crf, preset, _bitrate(bitrate) if bitrate is not None else None, tuple(options)
    )


def output_paths(pattern: str, views: list[NamedView]) -> list[Path]:
    """Each view's output file: ``{name}`` in ``pattern`` becomes the view's name (``{{`` and ``}}`` are
    literal braces). Any other ``{key}`` is refused: taken literally, a mistyped ``{view}`` wrote one file
    named ``out_{view}.mp4`` for every view."""
    try:
        paths = fill_pattern(pattern, "name", "the view's name", [item.name for item in views], required=False)
    except PanomapError as exc:
        raise click.BadParameter(exc.detail, param_hint="'-o'") from None
    if not placeholders(pattern) and len(views) > 1:
        raise click.UsageError("with several views the output pattern needs {name}, e.g. -o 'out_{name}.mp4'")
    return paths


# The signals that finish every output cleanly (SIGHUP where the system has it).
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, *((signal.SIGHUP,) if hasattr(signal, "SIGHUP") else ()))


@contextlib.contextmanager
def stop_on_signals(stop: threading.Event) -> Iterator[None]:
    """The first SIGINT, SIGTERM or SIGHUP (the terminal closed) sets ``stop`` (a clean finish);
    a second SIGINT aborts (KeyboardInterrupt), and a third, during the abort, kills at once."""
    previous: dict[Any, Any] = {}

    def handler(signum: int, frame: Any) -> None:
        if stop.is_set() and signum == signal.SIGINT:
            signal.signal(signal.SIGINT, signal.SIG_DFL)  # (the abort's clean-up is not itself interrupted)
            raise KeyboardInterrupt
        stop.set()

    for signum in STOP_SIGNALS:
        previous[signum] = signal.signal(signum, handler)
    try:
        yield
    finally:
        for signum, old in previous.items():
            signal.signal(signum, old)


class _Progress(ProgressBar):
    """The run's bar: frames, fps, ETA when the length is known."""

    def __call__(self, done: int, expected: int | None) -> None:
        self.update(done, expected)


@click.command()
@click.argument("table", type=PATH)
@click.argument("sources", metavar="INPUT...", nargs=-1, required=True)
@click.option(
    "-o",
    "--output",
    "pattern",
    required=True,
    metavar="PATTERN",
    help="Output file per view; {name} becomes the view's name (e.g. 'out_{name}.mp4').",
)
@click.option(
    "--view",
    "specs",
    multiple=True,
    metavar="SPEC",
    help="A view, as KIND:key=value,... with KIND one of "
    + ", ".join(KINDS)
    + " (see the View SPECs above). Repeatable.",
)
@click.option(
    "--views", "views_file", type=PATH, help="A JSON or YAML file of named views (see the --views file above)."
)
@click.option("--codec", default="libx264", show_default=True, help="Video encoder (FFmpeg name).")
@click.option("--pix-fmt", default="yuv420p", show_default=True, help="Encoded pixel format.")
@click.option("--crf", type=click.IntRange(0, 63), default=20, show_default=True, help="Quality (x264/x265).")
@click.option("--preset", default="veryfast", show_default=True, help="Speed preset (x264/x265).")
@click.option("--bitrate", help="Target bit rate instead of --crf, e.g. 8M.")
@click.option(
    "--encoder-option",
    "encoder_options",
    multiple=True,
    metavar="KEY=VALUE",
    help="More options of the encoder (as ffmpeg -h encoder=NAME lists them); an unknown one is refused. Repeatable.",
)
@click.option("--start", type=FINITE, default=0.0, show_default=True, help="Start at this time (s).")
@click.option("--duration", type=FINITE, help="Stop after this many seconds of input.")
@click.option("--every", type=click.IntRange(min=1), default=1, show_default=True, help="Keep every N-th frame.")
@click.option("--no-audio", is_flag=True, help="Do not copy the input's audio.")
@click.option("--interp", type=click.Choice(list(INTERPOLATIONS)), default="linear", show_default=True)
@click.option("--table-sampling", type=click.Choice(SAMPLINGS), default="bilinear", show_default=True)
@click.option(
    "--fixed-point",
    is_flag=True,
    help="OpenCV's fixed-point maps (1/32 px, less memory; slower on YUV planes) instead of float maps.",
)
@click.option(
    "--reconnect",
    "attempts",
    type=click.IntRange(min=0),
    metavar="N",
    help="A live input that drops: reconnect attempts per drop, waiting 0.5, 1, 2, 4, 8, 8 ... s "
    "before each, writing on into new files (out_001.mp4, ...) [default: 5].",
)
@click.option("--no-reconnect", is_flag=True, help="End the run when a live input drops.")
@click.option(
    "--timeout",
    "timeout_s",
    type=POSITIVE,
    default=10.0,
    show_default=True,
    help="A live input silent this long (s) has dropped; also the limit for each connection attempt.",
)
def video(
    table: Path,
    sources: tuple[str, ...],
    pattern: str,
    specs: tuple[str, ...],
    views_file: Path | None,
    codec: str,
    pix_fmt: str,
    crf: int,
    preset: str,
    bitrate: str | None,
    encoder_options: tuple[str, ...],
    start: float,
    duration: float | None,
    every: int,
    no_audio: bool,
    interp: str,
    table_sampling: str,
    fixed_point: bool,
    attempts: int | None,
    no_reconnect: bool,
    timeout_s: float,
) -> None:
    """Unwarp a video (file, RTSP/HTTP URL or V4L2 device) into one video per view.

    Every output keeps the input's frame rate and timestamps, and a copy of its
    audio. Frames that fail to decode are reported and skipped. Live inputs run
    until stopped: Ctrl-C (or SIGTERM, or SIGHUP) finishes every output cleanly,
    playable.

    A live input that drops (it ends, a read fails, or it is silent for
    --timeout) is reconnected with backoff; the files so far are closed,
    complete, and the output goes on in numbered segments: out.mp4, then
    out_001.mp4, out_002.mp4, ... Each gap is one line on stderr and is in
    the summary. If every attempt fails, the run ends with exit code 1, every
    segment written kept. --no-reconnect ends the run at the first drop
    (exit code 0).

    \b
    View SPECs (angles in degrees, lengths in world units; pairs A:B; sizes WxH):
      panorama:size=2048x512,start=0
      cylinder:distance=2,band=-2.45:0.15,size=2048x560,start=0
      plane:distance=1.8,width=2.4,band=-2.45:0.15,azimuth=90,size=800x860
      perspective:yaw=30,pitch=-20,roll=0,fov=90,size=1280x720
      floor:z=0,x=0:6,y=0:5,size=1200x1000   (or resolution=0.005)
      equirect:yaw=0,size=2048x1024          (the whole sphere, as ffmpeg v360's e)
    Any SPEC may add name=NAME (its output's {name}; default: the kind).

    \b
    A --views file maps names to the same keys plus "kind":
      {"door": {"kind": "perspective", "yaw": 90, "pitch": -20, "fov": 90, "size": "1280x720"}}

    \b
    Example:
      panomap video cam.npz omni.mp4 -o 'out_{name}.mp4' \\
          --view panorama:size=2048x512 --view perspective:yaw=30,pitch=-20,fov=90,size=1280x720

    A rig file (a 360 camera, a surround view: panomap import of a camchain, rig make) in place of the table
    blends one view of its cameras: give the
    one video holding them side by side (a dual-fisheye camera's), or one video per camera in the rig's order
    (read in step, to the shortest).
    """
    named = views_of(specs, views_file)
    paths = output_paths(pattern, named)
    encoder = encoder_settings(codec, pix_fmt, crf, preset, bitrate, encoder_options)
    try:
        encoder.check()
        selection = Selection(start, duration, every)
    except PanomapError as exc:
        raise usage_error(exc) from None
    if no_reconnect and attempts:
        raise click.UsageError("give --reconnect N or --no-reconnect, not both")
    reconnect = Reconnect(attempts=0 if no_reconnect else (5 if attempts is None else attempts), timeout_s=timeout_s)
    if is_rig_file(table):
        if len(named) != 1:
            raise click.UsageError(f"a rig's video blends one view, not {len(named)}: give one --view")
        if fixed_point or attempts:
            raise click.UsageError(f"{'--fixed-point' if fixed_point else '--reconnect'} is not for a rig's video")
        rig_video(table, sources, paths[0], named[0].view, encoder, selection, not no_audio, table_sampling, interp,
                  timeout_s)  # fmt: skip
        return
    if len(sources) != 1:
        raise click.UsageError(f"a table takes one input, not {len(sources)} (several cameras make a rig)")
    source = sources[0]
    check_outputs(
        [("the table", table), ("the input", local_file(source))],
        [(f"the output of view {item.name}", path) for item, path in zip(named, paths, strict=True)],
    )
    with rotation_warned([Path(source)] if local_file(source) is not None else []):
        loaded = load_table(table)
    stop = threading.Event()
    progress = _Progress(not quiet() and sys.stderr.isatty())
    try:
        with stop_on_signals(stop):
            report = unwarp_video(
                loaded,
                source,
                [ViewOutput(item.view, path) for item, path in zip(named, paths, strict=True)],
                encoder=encoder,
                selection=selection,
                audio=not no_audio,
                sampling=table_sampling,
                interpolation=interp,
                fixed_point=fixed_point,
                stop=stop,
                progress=progress,
                warn=progress.write,
                reconnect=reconnect,
            )
    finally:
        progress.close()
    last = report.gaps[-1] if report.gaps else None
    if last is not None and last.outcome in ("stopped", "not reconnecting"):
        click.echo(last.describe(source), err=True)
    if not quiet():
        click.echo(summary(report))
    if last is not None and last.outcome == "gave up":
        raise PanomapError(last.describe(source) + " (the segments written so far are kept)")


def rig_video(
    rig_path: Path,
    sources: tuple[str, ...],
    output: Path,
    view: Any,
    encoder: EncoderSettings,
    selection: Selection,
    audio: bool,
    sampling: str,
    interp: str,
    timeout_s: float,
) -> None:
    """``panomap video RIG INPUT... --view SPEC``: the rig's blended view of its videos."""
    if interp not in ("linear", "nearest"):
        raise click.BadParameter("a rig's video reads linear or nearest", param_hint="'--interp'")
    with rotation_warned([Path(source) for source in sources if local_file(source) is not None]):
        rig = load_rig(rig_path)
        try:
            check_rig_sources(rig, sources)
        except PanomapError as exc:
            raise usage_error(exc) from None
        check_outputs(
            [("the rig", rig_path), *((f"input {k + 1}", local_file(s)) for k, s in enumerate(sources))],
            [("the output", output)],
        )
    stop = threading.Event()
    progress = _Progress(not quiet() and sys.stderr.isatty())
    try:
        with stop_on_signals(stop):
            report = unwarp_rig_video(
                rig, list(sources), output, view, encoder=encoder, selection=selection, audio=audio,
                sampling=sampling, interpolation=interp, stop=stop, progress=progress, warn=progress.write,
                timeout_s=timeout_s,
            )  # fmt: skip
    finally:
        progress.close()
    if not quiet():
        click.echo(summary(report).replace("unwarped", f"blended {rig.count} cameras' view:", 1))


def summary(report: VideoReport) -> str:
    """The run in one line: frames, speed, audio, gaps and the files written."""
    if report.interrupted and report.frames_written == 0:
        return f"stopped by a signal before the first frame, after {report.seconds:.1f} s: nothing written"
    fps = report.frames_written / report.seconds if report.seconds > 0 else 0.0
    how = "stopped by a signal after" if report.interrupted else "unwarped"
    extra = f", {report.frames_skipped} skipped" if report.frames_skipped else ""
    gaps = [gap for gap in report.gaps if gap.outcome == "resumed"]
    if gaps:
        each = ", ".join(f"{gap.seconds:.1f} s after frame {gap.frames_before}" for gap in gaps)
        extra += f", {len(gaps)} gap{'s' if len(gaps) > 1 else ''} ({each}), {report.segments} segments"
    if report.gave_up:
        how = "unwarped, until the input was lost,"
    return (
        f"{how} {report.frames_written} frames{extra} in {report.seconds:.1f} s ({fps:.1f} fps)"
        f"{', audio copied' if report.audio else ''}: " + ", ".join(str(path) for path in report.outputs)
    )
