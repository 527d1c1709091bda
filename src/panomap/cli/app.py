"""The ``panomap`` command line: parses input, calls the library, reports.

Angles on the command line are in degrees; lengths in world units; sizes as
``WxH`` (views) or ``MxN`` (tables). Bad input gets one line on stderr,
naming the file and the problem, and a non-zero exit code (1 for bad input,
2 for bad usage); outputs are written to a temporary name and renamed when
complete.
"""

from __future__ import annotations

import importlib
import sys
from typing import Any, NoReturn

import click

from .. import __version__
from ..errors import PanomapError, printable
from .options import quiet_option
from .views import VIEW_COMMANDS

# Every command, registered here and nowhere else: its name, and the module (of this package) and attribute that
# hold it. A command's module is imported when the command is run or listed, so that a command starts without
# the others' imports (the calibration's SciPy, the viewer, the demo's scenes: ~0.3 CPU-s of every start).
LAZY_COMMANDS: dict[str, tuple[str, str]] = {
    "fit": ("calibrate", "fit"),
    "centre": ("calibrate", "centre"),
    "info": ("calibrate", "info"),
    "project": ("points", "project"),
    "unproject": ("points", "unproject"),
    "video": ("video", "video"),
    "batch": ("batch", "batch"),
    "learn": ("learn", "learn"),
    "demo": ("demo", "demo"),
    # Calibrations of other tools in and out (issue 36).
    "import": ("interop", "import_"),
    "export": ("interop", "export"),
    # The live viewer (issue 37).
    "view": ("viewer", "view"),
    # Cameras that look any way (issue 51).
    "orient": ("interop", "orient"),
    "level": ("interop", "level"),
    # Rigs learned from pictures (issue 52).
    "rig": ("rigs", "rig"),
}


def _quiet(command: click.Command) -> click.Command:
    """``command`` (and a group's commands) with -q, declared once (issue 53)."""
    for each in (command, *getattr(command, "commands", {}).values()):
        if not any(param.name == "quiet" for param in each.params):
            each.params.append(quiet_option())
    return command


for _command in VIEW_COMMANDS:
    _quiet(_command)


def load_command(name: str) -> click.Command | None:
    """The command ``name`` (its module imported, -q added), or None for no such command."""
    if name not in LAZY_COMMANDS:
        return next((command for command in VIEW_COMMANDS if command.name == name), None)
    module, attribute = LAZY_COMMANDS[name]
    command: click.Command = getattr(importlib.import_module(f".{module}", __package__), attribute)
    return _quiet(command)


def __getattr__(name: str) -> Any:
    """``COMMANDS``: every command, each module imported (what the help and the tests list)."""
    if name == "COMMANDS":
        lazy = [load_command(command) for command in LAZY_COMMANDS]
        return (*VIEW_COMMANDS, *(command for command in lazy if command is not None))
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


# `panomap --help`'s order: a table (imported, learned from pictures or landmarks), what it holds, its views, then
# the rest; a command not named here comes after these, by name.
HELP_ORDER = (
    "import", "fit", "centre", "info", "orient", "level", *(str(command.name) for command in VIEW_COMMANDS),
    "video", "batch", "view", "learn", "rig", "project", "unproject", "export", "demo",
)  # fmt: skip


# Click 8.2 raises this for a group called without a command (8.1 printed the help itself).
_NO_ARGS_IS_HELP: type[click.UsageError] = getattr(
    click.exceptions, "NoArgsIsHelpError", type("_Never", (click.UsageError,), {})
)


def _fail(message: str, code: int = 1) -> NoReturn:
    click.echo(f"panomap: error: {printable(message)}", err=True)
    sys.exit(code)


class PanomapGroup(click.Group):
    """A group that reports every error in one line, without a traceback, and lists its commands in the order a
    new user meets them (:data:`HELP_ORDER`)."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        names = {*self.commands, *LAZY_COMMANDS}
        listed = [name for name in HELP_ORDER if name in names]
        return listed + sorted(name for name in names if name not in listed)

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        if cmd_name not in self.commands:
            command = load_command(cmd_name)
            if command is None:
                return None
            self.add_command(command, cmd_name)
        return self.commands[cmd_name]

    def main(self, *args: Any, **kwargs: Any) -> NoReturn:
        kwargs["standalone_mode"] = False
        try:
            result = super().main(*args, **kwargs)
        except _NO_ARGS_IS_HELP as exc:  # bare `panomap` (or a bare group): the help, as it is laid out
            click.echo(exc.ctx.get_help() if exc.ctx is not None else exc.format_message())
            sys.exit(0)
        except click.UsageError as exc:
            where = exc.ctx.command_path if exc.ctx is not None else "panomap"
            message = printable(" ".join(exc.format_message().split()))
            click.echo(f"{where}: error: {message} (see '{where} --help')", err=True)
            sys.exit(exc.exit_code)
        except click.ClickException as exc:
            _fail(" ".join(exc.format_message().split()), exc.exit_code)
        except click.Abort:
            _fail("interrupted", 130)
        except PanomapError as exc:
            # The first line; the figures behind it where the command was asked for them (fit --verbose).
            verbose = getattr(exc, "verbose", None)
            hint = " (more: --verbose)" if verbose is False and exc.figures else ""
            click.echo(f"panomap: error: {printable(' '.join(exc.summary.split()))}{hint}", err=True)
            if verbose and exc.figures:
                click.echo(printable(exc.figures, keep="\n"), err=True)
            sys.exit(1)
        except OSError as exc:
            _fail(f"{exc.filename or ''}: {exc.strerror or exc}".lstrip(": "))
        sys.exit(result if isinstance(result, int) else 0)


@click.group(
    cls=PanomapGroup,
    commands=list(VIEW_COMMANDS),
    context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100},
)
@click.version_option(__version__, prog_name="panomap")
def main() -> None:
    """Unwarp omni-images (mirror and fisheye cameras) with pano-mapping tables.

    \b
    First a table of the camera, one of three ways:
      panomap import calib_results.txt -o cam.npz    a calibration made elsewhere (OCamCalib, OpenCV,
                                                      Kalibr, COLMAP, BoofCV, Basalt, gyroflow, Hugin,
                                                      OpenCalib)
      panomap fit -o cam.npz --image 'shots/*.jpg'   learned from pictures: their straight lines and
                                                      checkerboards (--camera-height H for distances)
      panomap fit landmarks.csv -o cam.npz --camera X0 Y0 Z0 --image omni.png
                                                      fitted to landmarks (pixel u,v and world X,Y,Z)
    Then its views, of a picture, a video or a stream:
      panomap panorama cam.npz omni.png -o pano.png
      panomap equirect cam.npz omni.png -o sphere.png    the whole sphere (a camera looking any way)
      panomap perspective cam.npz omni.png -o ptz.png --yaw 270 --pitch -30 --fov 100
      panomap floor cam.npz omni.png -o floor.png --z 0 --x 0 6 --y 0 5 --resolution 0.01
      panomap video cam.npz omni.mp4 -o 'out_{name}.mp4' --view panorama:size=2048x512
    Several cameras in one (a 360 camera, a car's surround view): a rig, and every view takes it:
      panomap import camchain.yaml -o rig.npz --side-by-side --fov 190   a dual fisheye's calibration
      panomap equirect rig.npz frame.jpg -o sphere.png       blended across the seam (docs/rigs.md)
      panomap rig make|learn|place ...   a rig of tables, its turns from pictures, or floor landmarks
    panomap demo renders a simulated room and does all of it.

    Conventions: world Z up; azimuth counter-clockwise from +X seen from above;
    elevation negative below the camera; pixel (u, v) = (column, row) with the
    centre of the top-left pixel at (0, 0). See docs/conventions.md.
    """
