"""The ``panomap learn`` command: serve the learning page for one omni-image."""

from __future__ import annotations

from pathlib import Path

import click

from ..calibrate.landmarks.pairs import read_landmarks
from ..errors import PanomapError
from .local_page import serve_until_interrupted, server_options, warn_unless_loopback
from .options import FINITE, FOLDER, PATH, frame_time_option, read_omni, say_note, warn_orientation


@click.command("learn")
@click.argument("omni", type=PATH)
@click.option("--landmarks", type=PATH, help="Landmarks to start with (CSV u,v,X,Y,Z[,name] or JSON).")
@click.option(
    "--camera", nargs=3, type=FINITE, metavar="X0 Y0 Z0", help="Camera (mirror centre) position to start with."
)
@click.option(
    "--dir",
    "folder",
    type=FOLDER,
    default=Path("."),
    show_default=True,
    help="The only folder the page saves into and loads from.",
)
@server_options(8765, "lets other machines use the page (and save files)")
@frame_time_option
def learn(
    omni: Path,
    landmarks: Path | None,
    camera: tuple[float, float, float] | None,
    folder: Path,
    port: int,
    host: str,
    frame_time: float | None,
) -> None:
    """Learn a camera in the browser: click landmarks on OMNI, type their world points, save the table.

    Starts a local web server and prints its address; open it in a browser.
    Ctrl-C stops it. Files are saved only into --dir (default: here).
    """
    from ..learn.server import make_server
    from ..learn.session import Session

    if not folder.is_dir():
        raise PanomapError("the folder does not exist", folder)
    image = read_omni(omni, frame_time)
    warn_orientation(omni)
    preload = read_landmarks(landmarks) if landmarks is not None else None
    session = Session(image, omni.name, folder, preload, camera)
    if session.circles_note:
        say_note(f"{session.circles_note}")
    server = make_server(session, host, port)
    warn_unless_loopback(host, "anyone who can reach this machine can use the page and write files into the folder")
    serve_until_interrupted(server, "learn", f"serving {omni.name} at {server.url} (files in {session.folder})")
