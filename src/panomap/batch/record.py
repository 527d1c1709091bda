"""The record of a batch: one JSON line per finished output or failed input, appended as they come.

Each line is an object; a finished output::

    {"status": "done", "output": "/abs/out/north/0001_pano.jpg", "input": "/abs/cams/north/0001.jpg",
     "view": "pano", "key": "<sha256 of what made it>", "frames": 1, "bytes": 812345,
     "sha256": "<of the output file>", "seconds": 0.21, "time": "2026-05-09T21:14:03+00:00"}

a failed input (after its retries)::

    {"status": "failed", "input": "/abs/cams/north/0002.jpg", "key": "...", "error": "...", "time": "..."}

Only the driver (the process that runs the job) writes the record, one line at a time,
flushed and synced, so that a job killed at any moment leaves whole lines (and at
most one cut last line, which is ignored when read back). The last line about an output
wins. An output is complete when its last line says done, its key is the job's, and the
file is there with the recorded size and modification time; everything else is redone.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterable
from dataclasses import asdict, dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from ..errors import PanomapError
from .job import Item


@dataclass(frozen=True)
class Done:
    """A finished output: what it is, what made it, and what it holds."""

    output: str
    input: str
    view: str
    key: str
    frames: int
    bytes: int
    sha256: str
    mtime_ns: int
    seconds: float


@dataclass(frozen=True)
class Failed:
    """An input that failed (after its retries), with the error, in one line."""

    input: str
    key: str
    error: str


def _now() -> str:
    return datetime.now(UTC).isoformat(timespec="seconds")


class Record:
    """The JSON-lines record at ``path``: what earlier runs finished, and where this run appends."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path).absolute()
        self.done: dict[str, Done] = {}
        self.failed: dict[str, Failed] = {}
        self._cut = False
        folder = self.path.parent
        if not folder.is_dir():
            raise PanomapError("its folder does not exist", self.path)
        if self.path.exists():
            self._read()

    def _read(self) -> None:
        try:
            text = self.path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise PanomapError(f"cannot read the record ({exc.__class__.__name__}: {exc})", self.path) from None
        lines = text.splitlines()
        self._cut = bool(text) and not text.endswith("\n")  # a last line cut by a kill: the next entry starts anew
        for number, line in enumerate(lines, start=1):
            if not line.strip():
                continue
            try:
                entry = json.loads(line)
            except (json.JSONDecodeError, RecursionError):
                if line.lstrip().startswith("{"):
                    continue  # a line cut by a kill
                entry = None
            if not isinstance(entry, dict) or entry.get("status") not in ("done", "failed"):
                raise PanomapError(
                    f"not a batch record: line {number} is not one of its entries (a JSON object with a status of "
                    "done or failed); give --record a record of panomap batch, or a new file",
                    self.path,
                )
            status = entry.pop("status", None)
            entry.pop("time", None)
            try:
                if status == "done":
                    done = Done(**entry)
                    self.done[done.output] = done
                elif status == "failed":
                    failed = Failed(**entry)
                    self.failed[failed.input] = failed
            except TypeError:
                continue  # a line of another format: its output is redone

    def complete(self, item: Item) -> bool:
        """Whether every output of ``item`` is recorded as done with the item's key, and still there
        as recorded (size and modification time)."""
        for output in item.outputs:
            done = self.done.get(str(output.path))
            if done is None or done.key != item.key:
                return False
            try:
                info = output.path.stat()
            except OSError:
                return False
            if info.st_size != done.bytes or info.st_mtime_ns != done.mtime_ns:
                return False
        return True

    def _append(self, entries: Iterable[dict[str, Any]]) -> None:
        text = "\n" * self._cut + "".join(json.dumps(entry, allow_nan=False) + "\n" for entry in entries)
        self._cut = False
        try:
            with self.path.open("a", encoding="utf-8") as handle:
                handle.write(text)
                handle.flush()
                os.fsync(handle.fileno())
        except OSError as exc:
            raise PanomapError(f"cannot write the record ({exc.strerror or exc})", self.path) from None

    def add_done(self, entries: Iterable[Done]) -> None:
        entries = list(entries)
        self._append({"status": "done", **asdict(entry), "time": _now()} for entry in entries)
        for entry in entries:
            self.done[entry.output] = entry
            self.failed.pop(entry.input, None)

    def add_failed(self, entry: Failed) -> None:
        self._append([{"status": "failed", **asdict(entry), "time": _now()}])
        self.failed[entry.input] = entry
