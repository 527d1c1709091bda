"""The ``panomap view`` command: look around in a source through a table, live, in the browser."""

from __future__ import annotations

import signal
from pathlib import Path

import click

from ..errors import PanomapError
from .options import PATH


@click.command("view")
@click.argument("table_path", metavar="TABLE", type=PATH)
@click.argument("source_name", metavar="SOURCE")
@click.option(
    "--port", type=click.IntRange(0, 65535), default=8766, show_default=True, help="Port; 0 picks a free one."
)
@click.option(
    "--host",
    default="127.0.0.1",
    show_default=True,
    help="Address to listen on. Anything but loopback shows the source to whoever can reach this machine.",
)
def view(table_path: Path, source_name: str, port: int, host: str) -> None:
    """Look around in SOURCE through TABLE in the browser: drag to pan and tilt, wheel to zoom.

    SOURCE is an omni-image, a video file, or a live stream or capture device (whatever
    `panomap video` takes: rtsp://..., http://..., /dev/video0). The page unwarps on the
    browser's GPU (WebGL2) with the same conventions as `panomap perspective`, keeps the
    view in its address (#yaw=30&pitch=-20&fov=90), and gives the matching command line.

    Starts a local web server and prints its address; open it in a browser. Ctrl-C stops it.

    \b
    Example:
      panomap view cam.npz omni.jpg
      panomap view cam.npz rtsp://camera.local/stream --port 8080
    """
    from ..io.local_web import is_loopback
    from ..table.file import load_table
    from ..video.source import is_live
    from ..viewer.server import make_server
    from ..viewer.source import open_source

    table = load_table(table_path)
    source = open_source(source_name)
    if table.image_size is not None and tuple(table.image_size) != source.size:
        width, height = source.size
        expected = table.image_size
        raise PanomapError(
            f"its frames are {width} x {height}, the table {table_path} is for {expected[0]} x {expected[1]} images",
            source_name if is_live(source_name) else Path(source_name),
        )
    if not is_loopback(host):
        click.echo(
            f"panomap: warning: listening on {host}, not loopback: whoever can reach this machine sees the source",
            err=True,
        )
    server = make_server(table, table_path.name, source, host, port)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    shown = source.name if source.kind == "live" else Path(source.name).name
    click.echo(
        f"panomap view: showing {shown} ({source.kind}) through {table_path.name} at {server.url}; Ctrl-C stops it"
    )
    try:
        server.serve_forever()
    except KeyboardInterrupt:
        click.echo("panomap view: stopped")
    finally:
        server.server_close()
        signal.signal(signal.SIGINT, previous)
