"""Live inputs that drop: when to reconnect, how long to wait, and where the output goes on.

A live input (a URL or a capture device) whose length is unknown has *dropped*
when it ends, fails to read, or sends nothing for ``Reconnect.timeout_s``. The
run then closes every view's file (complete and playable, renamed into place),
reconnects with exponential backoff, and goes on in new files, one *segment*
per connection: ``out.mp4``, then ``out_001.mp4``, ``out_002.mp4``, ... (MP4 and
most containers cannot be appended to once closed, and a reconnected stream
restarts its timestamps). A file served over HTTP, whose size is known, is read
once, as a file is.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from ..errors import PanomapError


@dataclass(frozen=True)
class Reconnect:
    """How a live input that drops is reconnected.

    Parameters
    ----------
    attempts : int
        Connection attempts per drop before giving up (a connection that
        drops again before its first frame counts as a failed attempt); 0
        ends the run at the first drop.
    first_wait_s : float
        Wait before the first attempt (s); each further attempt waits twice
        as long as the one before ...
    max_wait_s : float
        ... up to this (s).
    timeout_s : float
        A live input that sends nothing for this long (s) has dropped; also
        how long one connection attempt may take.
    """

    attempts: int = 5
    first_wait_s: float = 0.5
    max_wait_s: float = 8.0
    timeout_s: float = 10.0

    def __post_init__(self) -> None:
        if self.attempts < 0:
            raise PanomapError(f"reconnect attempts must be 0 or more, not {self.attempts}")
        for name, said in (("first_wait_s", "first wait"), ("max_wait_s", "longest wait"), ("timeout_s", "timeout")):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise PanomapError(f"the reconnect's {said} must be a finite time of more than 0 s, not {value:g}")

    def wait_s(self, attempt: int) -> float:
        """The wait (s) before attempt number ``attempt`` (1, 2, ...) after a drop."""
        return min(self.first_wait_s * 2.0 ** (attempt - 1), self.max_wait_s)


def segment_path(path: Path, number: int) -> Path:
    """Segment ``number``'s file for the output ``path``: ``path`` itself for 0, else ``STEM_NNN.SUFFIX``."""
    return path if number == 0 else path.with_name(f"{path.stem}_{number:03d}{path.suffix}")


def check_segment_names(paths: Sequence[Path]) -> None:
    """Refuse outputs where one view's later segments would overwrite another view's file."""
    for path in paths:
        pattern = re.compile(re.escape(path.stem) + r"_\d{3,}" + re.escape(path.suffix))
        for other in paths:
            if other != path and other.parent == path.parent and pattern.fullmatch(other.name):
                raise PanomapError(
                    f"after a drop of the live input, the segments of {path.name} ({path.stem}_001{path.suffix}, "
                    "...) would overwrite this output: give the views other names",
                    other,
                )
