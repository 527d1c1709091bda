"""The progress bar of the long commands (``video``, ``batch``): one tqdm bar on stderr.

Shown only on a terminal and without ``-q``. A terminal that reports 0 columns (a serial
console, some CI runners and multiplexers) gets a bar of :data:`FALLBACK_COLUMNS`; tqdm's own
sizing drew nothing there. Messages written while the bar is up go above it, with every
control character escaped (they may quote names from files).
"""

from __future__ import annotations

import os
import sys
from typing import IO, Any

import click

from ..errors import printable

FALLBACK_COLUMNS = 80


def terminal_columns(stream: IO[str]) -> int | None:
    """The width of the terminal ``stream`` writes to, or None where it reports none (or 0)."""
    try:
        columns = os.get_terminal_size(stream.fileno()).columns
    except (AttributeError, OSError, ValueError):
        return None
    return columns if columns > 0 else None


class ProgressBar:
    """A tqdm bar of frames (fps, ETA when the total is known), made on the first update; nothing when
    ``enabled`` is False.

    Parameters
    ----------
    enabled : bool
        Whether to draw at all (a terminal, no ``-q``).
    stream : file, optional
        Where to draw (default: stderr).
    """

    def __init__(self, enabled: bool, stream: IO[str] | None = None) -> None:
        self.enabled = enabled
        self.stream = stream
        self.bar: Any = None

    def update(self, done: int, total: int | None, postfix: str | None = None) -> None:
        """Show ``done`` frames of ``total`` (None: unknown), with ``postfix`` after the rate."""
        if not self.enabled:
            return
        if self.bar is None:
            from tqdm import tqdm

            stream = self.stream or sys.stderr
            columns = terminal_columns(stream)
            self.bar = tqdm(
                total=total,
                unit="frame",
                file=stream,
                leave=True,
                dynamic_ncols=columns is not None,
                ncols=None if columns is not None else FALLBACK_COLUMNS,
            )
        if postfix is not None:
            self.bar.set_postfix_str(postfix, refresh=False)
        self.bar.update(done - self.bar.n)

    def write(self, message: str) -> None:
        """One line on stderr, above the bar when it is up."""
        message = printable(message)
        if self.bar is not None:
            self.bar.write(message, file=self.stream or sys.stderr)
        else:
            click.echo(message, err=True)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
