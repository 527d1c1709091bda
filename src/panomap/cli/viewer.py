"""The ``panomap view`` command: look around in a source through a table, live, in the browser."""

from __future__ import annotations

from pathlib import Path

import click

from ..errors import PanomapError
from .local_page import serve_until_interrupted, server_options, warn_unless_loopback
from .options import PATH


@click.command("view")
@click.argument("table_path", metavar="TABLE", type=PATH)
@click.argument("source_names", metavar="SOURCE...", nargs=-1, required=True)
@server_options(8766, "shows the source to whoever can reach this machine")
def view(table_path: Path, source_names: tuple[str, ...], port: int, host: str) -> None:
    """Look around in SOURCE through TABLE in the browser: drag to pan and tilt, wheel to zoom.

    SOURCE is an omni-image, a video file, or a live stream or capture device (whatever
    `panomap video` takes: rtsp://..., http://..., /dev/video0). The page unwarps on the
    browser's GPU (WebGL2) with the same conventions as `panomap perspective`, keeps the
    view in its address (#yaw=30&pitch=-20&fov=90), and gives the matching command line.

    A rig file (panomap import of a camchain, panomap rig make) in place of TABLE blends its cameras as
    `panomap perspective RIG ...` does: give the one frame holding them all (a picture or a video file),
    or one still picture per camera in the rig's order.

    Starts a local web server and prints its address; open it in a browser. Ctrl-C stops it.

    \b
    Example:
      panomap view cam.npz omni.jpg
      panomap view cam.npz rtsp://camera.local/stream --port 8080
      panomap view dual.npz frame.jpg
    """
    from ..rig.file import is_rig_file
    from ..table.file import load_table
    from ..video.source import is_live
    from ..viewer.server import make_server
    from ..viewer.source import open_source

    if is_rig_file(table_path):
        _view_rig(table_path, list(source_names), port, host)
        return
    if len(source_names) != 1:
        raise click.UsageError(f"a table takes one source, not {len(source_names)} (several cameras make a rig)")
    source_name = source_names[0]
    table = load_table(table_path)
    source = open_source(source_name)
    if table.image_size is not None and tuple(table.image_size) != source.size:
        width, height = source.size
        expected = table.image_size
        raise PanomapError(
            f"its frames are {width} x {height}, the table {table_path} is for {expected[0]} x {expected[1]} images",
            source_name if is_live(source_name) else Path(source_name),
        )
    server = make_server(table, table_path.name, source, host, port)
    warn_unless_loopback(host, "whoever can reach this machine sees the source")
    shown = source.name if source.kind == "live" else Path(source.name).name
    serve_until_interrupted(
        server, "view", f"showing {shown} ({source.kind}) through {table_path.name} at {server.url}"
    )


def _view_rig(rig_path: Path, names: list[str], port: int, host: str) -> None:
    """``panomap view RIG SOURCE...``: the rig's blended view of its frame or pictures."""
    from ..rig.file import load_rig
    from ..viewer.rig_view import open_rig_source
    from ..viewer.server import make_server

    rig = load_rig(rig_path)
    try:
        rig_view, source = open_rig_source(rig, rig_path.name, names)
    except PanomapError as exc:
        if exc.source is None:
            raise PanomapError(exc.detail, rig_path) from None
        raise
    server = make_server(rig.tables[0], rig_path.name, source, host, port, rig=rig_view)
    warn_unless_loopback(host, "whoever can reach this machine sees the pictures")
    shown = ", ".join(Path(name).name for name in names)
    serve_until_interrupted(
        server,
        "view",
        f"showing {shown} ({source.kind}) through the rig {rig_path.name} of {rig.count} cameras at {server.url}",
    )
