"""``panomap project`` and ``unproject``: world points to pixels, pixels to rays."""

from __future__ import annotations

import csv
import io
import math
import sys
from pathlib import Path

import click
import numpy as np

from ..calibrate.landmarks.pairs import read_points
from ..errors import printable
from ..files import check_outputs, write_text_atomic
from ..geometry import ray_plane_points
from ..table.file import load_table
from ..table.sampling import SAMPLINGS
from .options import FINITE, PATH, say

STDOUT = "-"  # an output of this name is standard output, as for ffmpeg and most Unix tools


@click.command()
@click.argument("table", type=PATH)
@click.argument("points", type=PATH)
@click.option(
    "-o", "--output", type=PATH, required=True, help="CSV to write: the input columns plus u,v ('-': standard output)."
)
@click.option("--table-sampling", type=click.Choice(SAMPLINGS), default="bilinear", show_default=True)
def project(table: Path, points: Path, output: Path, table_sampling: str) -> None:
    """World points (CSV with X,Y,Z) to pixels through the table; u,v empty where not visible."""
    check_outputs([("the table", table), ("the points", points)], _outputs(output))
    loaded = load_table(table)
    read = read_points(points)
    header, rows = read.header, read.rows
    uv = loaded.project(read.values, table_sampling)
    keep = [i for i, name in enumerate(header) if name.lower() not in ("u", "v")]
    buffer = io.StringIO()
    writer = csv.writer(buffer, delimiter=read.delimiter, lineterminator="\n")
    writer.writerow([header[i] for i in keep] + ["u", "v"])
    for row, (u, v) in zip(rows, uv.tolist(), strict=True):
        seen = math.isfinite(u) and math.isfinite(v)
        pixel = [read.number(u, 4), read.number(v, 4)] if seen else ["", ""]
        writer.writerow([row[i] for i in keep] + pixel)
    visible = int(np.count_nonzero(np.all(np.isfinite(uv), axis=1)))
    _write(output, buffer.getvalue(), f"({visible} of {len(rows)} points visible)")


def _outputs(output: Path) -> list[tuple[str, Path]]:
    """The output file to check before any work: none for '-' (standard output)."""
    return [] if str(output) == STDOUT else [("the output", output)]


def _write(output: Path, text: str, summary: str) -> None:
    """``text`` to the file ``output`` (atomically), then "wrote OUTPUT SUMMARY"; for '-', ``text`` to standard
    output and the summary to standard error (so that the CSV can be piped). On a terminal, control characters
    from the points' names are escaped (a pipe or a file gets the CSV byte for byte)."""
    if str(output) == STDOUT:
        click.echo(printable(text, keep="\n\r\t") if sys.stdout.isatty() else text, nl=False)
        say(f"wrote standard output {summary}", err=True)
        return
    write_text_atomic(output, text)
    say(f"wrote {output} {summary}")


# ----------------------------------------------------------------------------- unproject


@click.command()
@click.argument("table", type=PATH)
@click.argument("pixels", type=PATH)
@click.option(
    "-o",
    "--output",
    type=PATH,
    required=True,
    help="CSV to write: the input columns plus azimuth_deg,elevation_deg ('-': standard output).",
)
@click.option(
    "--z", "z_plane", type=FINITE, help="Also give X,Y,Z where each pixel's ray meets the horizontal plane Z (world)."
)
def unproject(table: Path, pixels: Path, output: Path, z_plane: float | None) -> None:
    """Pixels (CSV with u,v) to rays: azimuth and elevation, empty outside the valid region."""
    check_outputs([("the table", table), ("the pixels", pixels)], _outputs(output))
    loaded = load_table(table)
    read = read_points(pixels, ("u", "v"))
    header, rows = read.header, read.rows
    theta, rho = loaded.unproject(read.values)
    added = ["azimuth_deg", "elevation_deg"] + (["X", "Y", "Z"] if z_plane is not None else [])
    replaced = {name.lower() for name in added}
    keep = [i for i, name in enumerate(header) if name.lower() not in replaced]
    world = (
        ray_plane_points(loaded.ray_origins(np.nan_to_num(theta), np.nan_to_num(rho)), theta, rho, z_plane)
        if z_plane is not None
        else np.full((len(rows), 0), np.nan)
    )
    buffer = io.StringIO()
    writer = csv.writer(buffer, delimiter=read.delimiter, lineterminator="\n")
    writer.writerow([header[i] for i in keep] + added)
    for row, azimuth, elevation, point in zip(rows, theta.tolist(), rho.tolist(), world.tolist(), strict=True):
        seen = math.isfinite(elevation)
        ray = [read.number(math.degrees(azimuth), 6), read.number(math.degrees(elevation), 6)] if seen else ["", ""]
        where = ["" if not math.isfinite(c) else read.number(c, 6) for c in point]
        writer.writerow([row[i] for i in keep] + ray + where)
    valid = int(np.count_nonzero(np.isfinite(rho)))
    message = f"({valid} of {len(rows)} pixels in the valid region"
    if z_plane is not None:
        reached = int(np.count_nonzero(np.all(np.isfinite(world), axis=1)))
        message += f"; {reached} {'ray reaches' if reached == 1 else 'rays reach'} the plane Z = {z_plane:g}"
    _write(output, buffer.getvalue(), message + ")")
