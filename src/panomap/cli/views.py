"""The view commands, one per registered view kind, generated from the kind's declared parameters (a rig file:
:mod:`.rigs`).

Each kind's parameters become options of the same names as its spec keys
(``--distance``, ``--band ZB ZT``, ``--yaw``...), angles in degrees, plus the
older names it declares (``--yaw-deg``); the values go through the view spec's
parsing, so a command and a spec build the same view.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import click
import numpy as np

from ..errors import PanomapError, printable
from ..files import all_or_none, check_outputs, check_room
from ..io.images import (
    check_image_output,
    image_file_bytes,
    map_file_bytes,
    pgm_map_paths,
    read_image,
    save_map,
    save_map_pgm,
    write_image,
)
from ..remap import INTERPOLATIONS, Remapper
from ..rig.file import is_rig_file
from ..table.file import load_table
from ..table.sampling import SAMPLINGS
from ..views import View, build_map, view_kinds
from ..views.base import Param, ParameterError, Value
from ..views.spec import view_from_params
from .options import (
    FINITE,
    PATH,
    SIZE,
    check_memory_for,
    refuse_video_as_picture,
    say_note,
    usage_error,
    warn_orientation,
)
from .options import quiet as quiet_given
from .rigs import render_rig


def view_options(function: Callable[..., Any]) -> Callable[..., Any]:
    """Arguments and options every view command shares."""
    decorators = [
        click.argument("table", type=PATH),
        click.argument("images", type=PATH, nargs=-1, required=True, metavar="IMAGE..."),
        click.option("-o", "--output", type=PATH, required=True, help="Output image (PNG, TIFF, JPEG...)."),
        click.option("--save-map", type=PATH, help="Also write the (H, W, 2) float32 (u, v) map as .npy."),
        click.option(
            "--each",
            metavar="PATTERN",
            help="With a rig: also write each camera's own unblended view, PATTERN with {camera} in it "
            "(cams/{camera}.png).",
        ),
        click.option(
            "--save-map-pgm",
            type=click.Path(path_type=str),
            metavar="PREFIX",
            help="Also write the map for ffmpeg's remap filter: PREFIX_x.pgm and PREFIX_y.pgm "
            "(16-bit, nearest pixel, 65535 where there is no source); a PREFIX that is a folder "
            "(ending in /) gets FOLDER/map_x.pgm and FOLDER/map_y.pgm.",
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
    maps: tuple[Path | None, str | None],
    interp: str,
    sampling: str,
    make_view: Callable[[], View],
    quiet: bool = False,
) -> None:
    save_map_path, pgm_prefix = maps
    view = make_view()
    if save_map_path is not None and save_map_path.suffix.lower() != ".npy":
        raise click.BadParameter(f"{save_map_path} is not a .npy file name", param_hint="--save-map")
    pgm_paths = pgm_map_paths(pgm_prefix) if pgm_prefix is not None else (None, None)
    check_outputs(
        [("the table", table_path), ("the input image", image_path)],
        [("the output", output), ("--save-map", save_map_path)]
        + [(f"--save-map-pgm's {path.name}", path) for path in pgm_paths if path is not None],
    )
    extra = [path for path in (save_map_path, *pgm_paths) if path is not None]
    table = load_table(table_path)
    size = view.output_size(table)
    check_room(map_file_bytes(size, save_map_path, pgm_paths))
    try:
        check_image_output(output, size)
    except PanomapError as exc:
        raise usage_error(exc, "-o") from None
    check_memory_for(view.memory_bytes(size), f"a view of {size[0]} x {size[1]} px")
    if view.needs_camera_height and table.info.get("camera_height_known") is False:
        say_note(
            f"{printable(str(table_path))} was learned from lines, which know no distance: its camera "
            "is at the origin, so heights and distances here are relative to the camera and their unit is yours "
            "(fit with --camera-height H for heights above the floor)"
        )
    try:
        image = read_image(image_path, table.image_size, f"the table {table_path}")
    except PanomapError as exc:
        refuse_video_as_picture(exc, table_path, image_path)
        raise
    warn_orientation(image_path)
    check_room([*map_file_bytes(size, save_map_path, pgm_paths), (output, image_file_bytes(size, image))], up_to=True)
    map_uv = build_map(table, view, sampling)
    remapper = Remapper(map_uv, (image.shape[1], image.shape[0]), interp)
    with all_or_none():
        write_image(output, remapper(image))
        if save_map_path is not None:
            save_map(save_map_path, map_uv)
        if pgm_prefix is not None:
            save_map_pgm(pgm_prefix, map_uv)
    if quiet or quiet_given():
        return
    valid = float(np.mean(np.all(np.isfinite(map_uv), axis=2)))
    click.echo(
        f"wrote {output} ({map_uv.shape[1]} x {map_uv.shape[0]}, {valid:.0%} of pixels with a source)"
        + "".join(f" and {path}" for path in extra)
    )


def _option(param: Param) -> click.Option:
    """The option of a declared parameter: ``--NAME`` and its older names, typed, in degrees for angles."""
    kwargs: dict[str, Any] = {
        "type": SIZE if param.value is Value.SIZE else FINITE,
        "nargs": 2 if param.value is Value.PAIR else 1,
        "metavar": param.shown_as,
        "help": param.help,
        "required": param.required,
    }
    if param.default is not None:
        kwargs |= {"default": param.default, "show_default": True}
    return click.Option([f"--{param.name}", *param.aliases, param.name], **kwargs)


def make_view(kind: str, values: Mapping[str, Any]) -> View:
    """The view of ``kind`` from its command's parsed options (None where not given).

    A missing one-of choice, or values the view refuses (out of range, or not
    fitting together), are usage errors (exit 2): a size out of bounds is
    reported under its option's name, the rest in the view's words. (What
    depends on the table, such as a floor above the camera, fails later: exit 1.)
    """
    cls = view_kinds()[kind]
    given = {key: value for key, value in values.items() if value is not None}
    if cls.one_of is not None and sum(key in given for key in cls.one_of.names) != 1:
        declared = {param.name: param for param in cls.params}
        choices = " or ".join(f"--{key} {declared[key].shown_as}" for key in cls.one_of.names)
        raise click.UsageError(f"give {cls.one_of.what} as {choices}, {cls.one_of.how_many}")
    try:
        return view_from_params(kind, given)
    except ParameterError as exc:
        if exc.key not in values:
            raise click.UsageError(str(exc)) from None
        raise click.BadParameter(exc.problem, param_hint=f"'--{exc.key}'") from None
    except PanomapError as exc:
        raise usage_error(exc) from None


class ViewCommand(click.Command):
    """A view command that names every required option missing at once (a floor map needs --z, --x and --y: said
    one at a time, a user ran the command three times to learn them)."""

    def parse_args(self, ctx: click.Context, args: list[str]) -> list[str]:
        given = list(args)
        try:
            return super().parse_args(ctx, args)
        except click.MissingParameter as exc:
            if not isinstance(exc.param, click.Option):
                raise
            opts, _, _ = self.make_parser(ctx).parse_args(args=given)
            missing = [param for param in self.params if isinstance(param, click.Option) and param.required
                       and opts.get(param.name) is None]  # fmt: skip
            if len(missing) < 2:
                raise
            shown = ", ".join(_option_shown(param) for param in missing)
            raise click.UsageError(f"missing options: {shown}", ctx) from None


def _option_shown(param: click.Option) -> str:
    """An option as a usage line names it: its first long name and its metavar (``--x XMIN XMAX``)."""
    name = next((opt for opt in param.opts if opt.startswith("--")), param.opts[0])
    return f"{name} {param.metavar}" if param.metavar else name


def view_command(kind: str) -> click.Command:
    """The command of a registered view kind: the shared arguments and options, then the kind's own."""
    cls = view_kinds()[kind]

    def run(
        table: Path,
        images: tuple[Path, ...],
        output: Path,
        save_map: Path | None,
        each: str | None,
        save_map_pgm: str | None,
        interp: str,
        table_sampling: str,
        **values: Any,
    ) -> None:
        maps = (save_map, save_map_pgm)
        if is_rig_file(table):  # a rig: one picture per camera, or one frame holding them all
            if save_map_pgm is not None:
                raise click.UsageError("--save-map-pgm writes one camera's map: a rig's view blends several")
            render_rig(table, images, output, save_map, interp, table_sampling, make_view(kind, values), each)
            return
        if each is not None:
            raise click.UsageError("--each writes each camera of a rig: give a rig file")
        if len(images) != 1:
            load_table(table)  # (a file that is neither a rig nor a table is named as such, not its pictures)
            raise click.UsageError(f"a table takes one picture, not {len(images)} (several cameras make a rig)")
        _render(table, images[0], output, maps, interp, table_sampling, lambda: make_view(kind, values))

    command = click.command(kind, cls=ViewCommand, help=cls.summary)(view_options(run))
    shared = {param.name for param in command.params}
    clashes = shared & {param.name for param in cls.params}
    if clashes:
        raise ValueError(f"view kind {kind!r} declares parameters that every view command has: {sorted(clashes)}")
    command.params += [_option(param) for param in cls.params]
    return command


# Every view command, in the registry's order.
VIEW_COMMANDS = tuple(view_command(kind) for kind in view_kinds())
