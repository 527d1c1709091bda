"""Option types the commands share: sizes, finite numbers, file paths.

Angles on the command line are in degrees; lengths in world units; sizes as
``WxH`` (views) or ``MxN`` (tables).
"""

from __future__ import annotations

import contextlib
import functools
import threading
from collections.abc import Callable, Iterable, Iterator, Sequence
from pathlib import Path
from typing import Any

import click
import numpy as np
from numpy.typing import NDArray

from ..errors import PanomapError, printable
from ..files import check_outputs
from ..values import NotFinite, finite_number


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
    """A finite real number (refuses nan and inf); at least ``minimum`` (more than it, if ``open``) when given."""

    name = "NUMBER"

    def __init__(self, minimum: float | None = None, open: bool = False) -> None:
        self.minimum = minimum
        self.open = open

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> float:
        try:
            number = finite_number(value)
        except NotFinite as exc:
            self.fail(str(exc), param, ctx)
        if self.minimum is not None and (number <= self.minimum if self.open else number < self.minimum):
            self.fail(f"{number:g} is not {'more than' if self.open else 'at least'} {self.minimum:g}", param, ctx)
        return number


class Tilt(click.ParamType):
    """``fit``, ``none``, or ``"DEG AZ_DEG"`` (one argument): the tilt off the vertical and its azimuth, deg."""

    name = "tilt"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        if isinstance(value, tuple) or value in ("fit", "none"):
            return value
        parts = str(value).replace(",", " ").split()
        try:
            if len(parts) != 2:
                raise NotFinite(value, number=False)
            tilt_deg, toward_deg = (finite_number(part) for part in parts)
        except NotFinite:
            self.fail(f"{value!r} is not 'fit', 'none' or two numbers 'DEG AZ_DEG'", param, ctx)
        if not 0 <= tilt_deg <= 45:
            self.fail(f"a tilt of {tilt_deg:g} deg: give 0 to 45 deg off the vertical", param, ctx)
        return (tilt_deg, toward_deg)


def orientation_option(help_text: str, required: bool = False) -> Any:
    """``--orientation YAW PITCH ROLL`` (deg): where a camera looks, as a perspective view's yaw, pitch and roll."""
    return click.option(
        "--orientation",
        nargs=3,
        type=FINITE,
        required=required,
        metavar="YAW PITCH ROLL",
        help=help_text,
    )


def orientation_rad(orientation: tuple[float, float, float] | None) -> tuple[float, float, float] | None:
    """Degrees from the command line to (yaw, pitch, roll) rad, the pitch checked (a usage error, exit 2)."""
    if orientation is None:
        return None
    yaw, pitch, roll = orientation
    if not -90.0 <= pitch <= 90.0:
        raise click.BadParameter(
            f"a pitch of {pitch:g} deg: give -90 (straight down) to 90 (straight up); turn the yaw and the roll "
            "by 180 deg instead",
            param_hint="'--orientation'",
        )
    return (float(np.radians(yaw)), float(np.radians(pitch)), float(np.radians(roll)))


def check_table_outputs(
    inputs: Iterable[tuple[str, Path | None]],
    output: Path,
    what: str = "a table",
    pictures: Sequence[tuple[str, Path | None, str]] = (),
) -> None:
    """The checks a command that writes a table (or a rig) runs on its outputs before any work.

    No output is one of ``inputs`` or another output and each can be written (:func:`~panomap.files.check_outputs`,
    inputs as ``(what, path)``); the ``-o`` for a table or a rig is named ``.npz`` (a table named cam.png reads as
    a broken picture to every other program); each picture written beside it, ``(option, path, what)`` (an
    overlay, a plot; a None path is skipped), is named ``.png``.
    """
    check_outputs(inputs, [("the output", output), *((option, path) for option, path, _ in pictures)])
    if output.suffix.lower() != ".npz":
        raise click.BadParameter(f"{output}: {what} is written as .npz (name it so)", param_hint="'-o'")
    for option, path, kind in pictures:
        if path is not None and path.suffix.lower() != ".png":
            raise click.BadParameter(f"{path}: {kind} is written as PNG (name it .png)", param_hint=f"'{option}'")


def refuse_same_input(paths: Sequence[Path], what: str, why: str, hint: Callable[[Path], str]) -> None:
    """Refuse, before any work, two of ``paths`` that are one file (the same path, a link, or the same bytes:
    :func:`panomap.files.same_input`): ``what`` names one ("picture", "frame"), ``why`` says what twice would do,
    ``hint(second)`` names the option or argument that took the second."""
    from ..files import same_input

    twice = same_input(paths)
    if twice is not None:
        first, second, how = twice
        raise click.BadParameter(
            f"{first} and {second} are one {what} ({how}): give each {what} once ({why})", param_hint=hint(second)
        )


def check_room_as(output: Path, like: Path) -> None:
    """Refuse, before any work, a table or rig written to ``output`` that its disk has no room for: one of the
    size of ``like``, the table or rig it is made from (its entries as many, :func:`panomap.files.check_room`)."""
    from ..files import check_room

    check_room([(output, like.stat().st_size)])


def check_radii(cutoff_radius: float | None, outer_radius: float | None) -> None:
    """``--cutoff-radius`` and ``--outer-radius``, both given: the cut-off below the outer one, before any work."""
    if cutoff_radius is not None and outer_radius is not None and not cutoff_radius < outer_radius:
        raise click.BadParameter(
            f"{cutoff_radius:g} px: the cut-off radius must be below the outer radius ({outer_radius:g} px)",
            param_hint="'--cutoff-radius'",
        )


def check_memory_for(needed: int, what: str) -> None:
    """Refuse, before the work, ``what`` (a view...) that needs ``needed`` bytes of memory, more than this machine
    has available (:func:`panomap.io.image_bounds.available_memory`; no check where it does not say)."""
    from ..io.image_bounds import available_memory

    def amount(size: int) -> str:
        return f"{size / 1e9:.1f} GB" if size >= 1e9 else f"{size / 1e6:.0f} MB"

    free = available_memory()
    if free is not None and needed > free:
        raise PanomapError(
            f"{what} needs about {amount(needed)} of memory, more than the {amount(free)} available: make it smaller"
        )


def usage_error(exc: PanomapError, option: str | None = None) -> click.UsageError:
    """A library error about an option's value, or about options given together, as a usage error (exit 2),
    in the library's words (under ``option``'s name when given)."""
    if option is None:
        return click.UsageError(str(exc))
    return click.BadParameter(str(exc), param_hint=f"'{option}'")


SIZE = Size()
FINITE = Finite()
POSITIVE = Finite(0.0, open=True)
NON_NEGATIVE = Finite(0.0)
TILT = Tilt()
PATH = click.Path(path_type=Path, dir_okay=False)


class Folder(click.Path):
    """A folder's path; the empty name, which would be the current folder unsaid, is refused (give ".")."""

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        if value == "":
            self.fail("an empty folder name: give one ('.' for the current folder)", param, ctx)
        return super().convert(value, param, ctx)


FOLDER = Folder(path_type=Path, file_okay=False)


def read_omni(
    path: Path,
    frame_time: float | None = None,
    expected_size: tuple[int, int] | None = None,
    expected_by: str = "the table",
) -> NDArray[Any]:
    """The omni-image at ``path`` (as :func:`panomap.io.images.read_image` reads it) or, where the file is a
    video, its frame at ``frame_time`` seconds (default: its first), with a note saying so on stderr (the
    centre, the circles and the landmarks are the same in every frame of a fixed camera); either refused where
    not of ``expected_size`` (W, H; ``expected_by`` expects it), as :func:`~panomap.io.images.read_image` says."""
    from ..io.images import MAX_IMAGE_PIXELS, UNKNOWN_FORMAT, check_image_size, read_image

    try:
        image = read_image(path, expected_size, expected_by)
    except PanomapError as exc:
        if exc.detail != UNKNOWN_FORMAT:
            raise
        from ..video.source import first_frame

        frame = first_frame(path, MAX_IMAGE_PIXELS, frame_time)
        if frame is None:
            raise
        check_image_size(path, (int(frame.shape[1]), int(frame.shape[0])), expected_size, expected_by)
        which = "its first frame" if not frame_time else f"its frame at {frame_time:g} s"
        say(f"panomap: note: {printable(str(path))} is a video: {which} is used (--frame-time SECONDS for another)",
            err=True)  # fmt: skip
        warn_rotation(path)
        return np.asarray(frame)
    if frame_time is not None:
        click.echo(f"panomap: warning: {path} is an image, not a video: --frame-time is ignored", err=True)
    return image


def is_video(path: Path) -> bool:
    """Whether the file is a video PyAV decodes (for the hint that ``panomap video`` unwarps it)."""
    from ..io.images import MAX_IMAGE_PIXELS
    from ..video.source import first_frame

    try:
        return first_frame(path, MAX_IMAGE_PIXELS) is not None
    except PanomapError:
        return True  # (frames too large to read: a video all the same)


def refuse_video_as_picture(exc: PanomapError, table: Path, path: Path) -> None:
    """Where ``exc`` is :func:`~panomap.io.images.read_image`'s refusal of ``path`` as no image it knows and the
    file is a video, refuse it saying that ``panomap video`` unwarps it through ``table`` (a table or a rig)."""
    from ..io.images import UNKNOWN_FORMAT

    if exc.source is not None and Path(exc.source) == path and exc.detail == UNKNOWN_FORMAT and is_video(path):
        raise PanomapError(
            f"it is a video: unwarp it with panomap video {table} {path} -o OUT.mp4 --view SPEC", path
        ) from None


def frame_time_option(command: Any) -> Any:
    """``--frame-time SECONDS``, for the commands that take one omni-image and may be given a video."""
    return click.option(
        "--frame-time",
        type=NON_NEGATIVE,
        metavar="SECONDS",
        help="Where the omni-image is a video: use its frame at this time (s) [default: its first frame].",
    )(command)


def warn_rotation(path: Path) -> None:
    """Print a warning line where the video at ``path`` asks players to turn its frames (its rotation metadata)."""
    from ..video.source import rotation_note

    _rotation_warning(path, rotation_note(path))


@contextlib.contextmanager
def rotation_warned(paths: Sequence[Path]) -> Iterator[None]:
    """The videos' rotation metadata (:func:`warn_rotation`'s) read on a thread while the block runs; after it,
    their warnings printed in order (none where the block fails: the reading is waited for alone). Reading it
    decodes a first frame (about 50 ms for a 3840 x 1920 H.264 frame): it goes on beside the block's own start
    (reading a table or a rig)."""
    from ..video.source import rotation_note

    notes: list[str | None] = []
    reader = threading.Thread(target=lambda: notes.extend(rotation_note(path) for path in paths),
                              name="panomap-rotation", daemon=True)  # fmt: skip
    reader.start()
    try:
        yield
    finally:
        reader.join()
    for path, note in zip(paths, notes, strict=False):
        _rotation_warning(path, note)


def _rotation_warning(path: Path, note: str | None) -> None:
    if note is not None:
        click.echo(f"panomap: warning: {printable(str(path))}: {note}", err=True)


def warn_orientation(path: Path) -> None:
    """Print a warning line where the image at ``path`` asks viewers to turn or mirror it (its EXIF orientation)."""
    from ..io.images import orientation_note

    note = orientation_note(path)
    if note is not None:
        click.echo(f"panomap: warning: {printable(str(path))}: {note}", err=True)


# ----------------------------------------------------------------------------- -q, declared once

_QUIET = "panomap.quiet"
QUIET_HELP = "No progress and no report: print nothing but the result asked for, warnings and errors."


def _remember_quiet(context: click.Context, _param: click.Parameter, value: bool) -> bool:
    if value:
        context.meta[_QUIET] = True
    return value


def quiet_option() -> click.Option:
    """``-q/--quiet``, one for every command (``panomap.cli.app`` adds it to each): read with :func:`quiet`."""
    return click.Option(
        ["-q", "--quiet"], is_flag=True, expose_value=False, is_eager=True, callback=_remember_quiet, help=QUIET_HELP
    )


def quiet() -> bool:
    """Whether the running command was given ``-q`` (False outside a command)."""
    context = click.get_current_context(silent=True)
    return context is not None and bool(context.meta.get(_QUIET))


def say(message: str, err: bool = False) -> None:
    """``message`` on stdout (stderr with ``err``) unless the command was given ``-q``."""
    if not quiet():
        click.echo(message, err=err)


def say_note(message: str) -> None:
    """``panomap: note: message`` on stderr unless the command was given ``-q``: what was chosen that the user
    should know but need not act on (warnings print whatever ``-q`` says)."""
    say(f"panomap: note: {message}", err=True)


def progress_bar(unit: str = "step") -> Any:
    """A :class:`panomap.cli.progress.ProgressBar` drawn on a terminal without ``-q``."""
    import sys

    from .progress import ProgressBar

    return ProgressBar(not quiet() and sys.stderr.isatty(), unit=unit)


# ----------------------------------------------------------------------------- refusals with option names

# The library's refusals say what to do in the user's words; fit adds the option that does it.
OPTION_HINTS = (
    ("give more pictures", "--image"),
    ("give it as a picture", "--image"),
    ("give its frames as pictures, each at its time", "--image VIDEO --frame-time S"),
    ("or give the axis", "--axis down|up"),
)


def with_option_names(command: Any) -> Any:
    """A command's body (``fit``'s), its refusals given the options that answer them (:data:`OPTION_HINTS`) and, with
    ``--verbose``, the figures behind them (printed by :class:`panomap.cli.app.PanomapGroup`)."""

    @functools.wraps(command)
    def run(*args: Any, verbose: bool, **kwargs: Any) -> Any:
        try:
            return command(*args, **kwargs)
        except PanomapError as exc:
            summary, newline, figures = exc.detail.partition("\n")
            for phrase, option in OPTION_HINTS:
                summary = summary.replace(phrase, f"{phrase} ({option})", 1)
            error = PanomapError(summary + newline + figures, exc.source)
            error.verbose = verbose  # type: ignore[attr-defined]
            raise error from None

    return run
