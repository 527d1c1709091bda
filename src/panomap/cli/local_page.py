"""What the commands that serve a local page share (`learn`, `view`): --port and --host, the warning for a
non-loopback address, and serving until Ctrl-C."""

from __future__ import annotations

import signal
from collections.abc import Callable
from typing import Any

import click

from ..io.local_web import LocalServer, is_loopback


def server_options(default_port: int, exposed: str) -> Callable[[Any], Any]:
    """``--port`` (default ``default_port``; 0 picks a free one) and ``--host`` (default loopback);
    ``exposed`` says what anything but loopback lets other machines do."""

    def decorate(command: Any) -> Any:
        command = click.option(
            "--host",
            default="127.0.0.1",
            show_default=True,
            help=f"Address to listen on. Anything but loopback {exposed}.",
        )(command)
        return click.option(
            "--port",
            type=click.IntRange(0, 65535),
            default=default_port,
            show_default=True,
            help="Port; 0 picks a free one.",
        )(command)

    return decorate


def warn_unless_loopback(host: str, consequence: str) -> None:
    """One warning line where ``host`` is not a loopback address: ``consequence`` says what that exposes (once it
    listens there: a host it cannot listen on is refused alone)."""
    if not is_loopback(host):
        click.echo(f"panomap: warning: listening on {host}, not loopback: {consequence}", err=True)


def serve_until_interrupted(server: LocalServer, command: str, banner: str) -> None:
    """Print ``panomap COMMAND: BANNER``, serve until Ctrl-C (then ``panomap COMMAND: stopped``), close the server.

    Ctrl-C (SIGINT) stops the server even where it was started ignoring SIGINT (a shell's background job,
    nohup), as Python then leaves it.
    """
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    click.echo(f"panomap {command}: {banner}; Ctrl-C stops it")
    try:
        server.serve_forever()
    except KeyboardInterrupt:
        click.echo(f"panomap {command}: stopped")
    finally:
        server.server_close()
        signal.signal(signal.SIGINT, previous)
