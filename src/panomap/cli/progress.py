"""The progress of the long commands (``fit``, ``video``, ``batch``...): one tqdm bar on stderr, or a line
per stage where the work has no count (a line that names the stage and ticks its seconds).
Shown only on a terminal and without ``-q`` (:func:`panomap.cli.options.quiet`): a bar or a stage line
is redrawn every second, so no long step is silent. A terminal that reports 0 columns (a serial
console, some CI runners and multiplexers) gets a bar of :data:`FALLBACK_COLUMNS`, one that reports
0 rows (a pty given no size) :data:`FALLBACK_ROWS`; tqdm's own sizing drew nothing there. Messages
written while the bar is up go above it, with every control character escaped (they may quote names
from files).
"""

from __future__ import annotations

import os
import sys
import threading
from typing import IO, Any

import click

from ..errors import printable

FALLBACK_COLUMNS = 80
# The rows assumed where the terminal reports 0 (a pty given no size: `script`, `docker exec -t`, some CI
# runners): tqdm, told 0, draws nothing at all.
FALLBACK_ROWS = 24
# Seconds between redraws of a bar whose count does not move (its elapsed time ticks).
TICK_S = 1.0


def terminal_columns(stream: IO[str]) -> int | None:
    """The width of the terminal ``stream`` writes to, or None where it reports none (or 0)."""
    return _terminal_size(stream)[0]


def _terminal_size(stream: IO[str]) -> tuple[int | None, int | None]:
    """(columns, rows) of the terminal ``stream`` writes to, each None where it reports none (or 0)."""
    try:
        size = os.get_terminal_size(stream.fileno())
    except (AttributeError, OSError, ValueError):
        return None, None
    return (size.columns or None), (size.lines or None)


class ProgressBar:
    """A tqdm bar of ``unit`` (rate, ETA when the total is known), made on the first update, or a line per
    stage (:meth:`stage`); nothing when ``enabled`` is False. Redrawn every :data:`TICK_S` seconds.

    Parameters
    ----------
    enabled : bool
        Whether to draw at all (a terminal, no ``-q``).
    stream : file, optional
        Where to draw (default: stderr).
    unit : str
        What the bar counts (``"frame"``, ``"step"``).
    """

    def __init__(self, enabled: bool, stream: IO[str] | None = None, unit: str = "frame") -> None:
        self.enabled = enabled
        self.stream = stream
        self.unit = unit
        self.bar: Any = None
        self._counted = False
        self._stop: threading.Event | None = None
        self._ticker: threading.Thread | None = None

    def _make(self, total: int | None, **kwargs: Any) -> None:
        from tqdm import tqdm

        stream = self.stream or sys.stderr
        columns, rows = _terminal_size(stream)
        self.bar = tqdm(
            total=total,
            file=stream,
            leave=True,
            dynamic_ncols=columns is not None,
            ncols=None if columns is not None else FALLBACK_COLUMNS,
            nrows=None if rows is not None else FALLBACK_ROWS,  # (tqdm draws nothing on a terminal of 0 rows)
            **kwargs,
        )
        stop = self._stop = threading.Event()
        bar = self.bar

        def tick() -> None:
            while not stop.wait(TICK_S):
                bar.refresh()

        self._ticker = threading.Thread(target=tick, name="panomap-progress", daemon=True)
        self._ticker.start()

    def update(self, done: int, total: int | None, postfix: str | None = None) -> None:
        """Show ``done`` of ``total`` (None: unknown), with ``postfix`` after the rate."""
        if not self.enabled:
            return
        if self.bar is not None and not self._counted:
            self.close()
        if self.bar is None:
            self._make(total, unit=self.unit)
            self._counted = True
        if postfix is not None:
            self.bar.set_postfix_str(printable(postfix), refresh=False)
        self.bar.update(done - self.bar.n)

    def stage(self, what: str) -> None:
        """A line for a step that has no count: ``what`` and its seconds, ticking; the previous stage's line
        (or bar) stays above it."""
        if not self.enabled:
            return
        self.close()
        self._make(None, desc=printable(what), bar_format="{desc}: {elapsed}")
        self._counted = False

    def write(self, message: str) -> None:
        """One line on stderr, above the bar when it is up."""
        message = printable(message)
        if self.bar is not None:
            self.bar.write(message, file=self.stream or sys.stderr)
        else:
            click.echo(message, err=True)

    def close(self) -> None:
        if self._stop is not None and self._ticker is not None:
            self._stop.set()
            self._ticker.join()
            self._stop = self._ticker = None
        if self.bar is not None:
            self.bar.close()
            self.bar = None
