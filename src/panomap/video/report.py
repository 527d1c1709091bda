"""What a run of :func:`panomap.video.unwarp.unwarp_video` did."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

# How a gap in a live input ended:
# "resumed": reconnected, the run went on in the next segment;
# "gave up": every reconnect attempt failed, the run ended;
# "stopped": stopped (a signal, ``stop``) while reconnecting, the run ended;
# "not reconnecting": reconnecting is off (``Reconnect(attempts=0)``), the run ended at the drop.
GapOutcome = Literal["resumed", "gave up", "stopped", "not reconnecting"]


@dataclass(frozen=True)
class Gap:
    """A stretch of a live input that was lost when it dropped, and how it ended.

    Parameters
    ----------
    reason : str
        Why the input dropped: ``"the stream ended"``, a read error
        (``"Connection reset by peer"``) or ``"no data for 10 s"``.
    frames_before : int
        Frames written (in all segments) before the gap.
    start_s : float
        When the last frame before the gap was received, in seconds since the run
        started (wall clock).
    seconds : float
        The gap's length (wall clock, s): from the last frame received before it
        to the first frame received after it; for a gap the run ended in, to
        when reconnecting ended.
    attempts : int
        Connection attempts made (the one that succeeded included).
    outcome : {"resumed", "gave up", "stopped", "not reconnecting"}
    segment : int or None
        The number of the segment that follows it (1 for ``out_001.mp4``);
        None where the run ended in it.
    last_failure : str or None
        Why the last failed attempt failed (``"cannot open it as a video
        (Connection refused)"``); None if none failed.
    """

    reason: str
    frames_before: int
    start_s: float
    seconds: float
    attempts: int
    outcome: GapOutcome
    segment: int | None = None
    last_failure: str | None = None

    def describe(self, source: str) -> str:
        """One line: where the gap was, how long, and how it ended."""
        head = f"{source}: the input dropped after frame {self.frames_before} ({self.reason})"
        tries = f"{self.attempts} attempt{'s' if self.attempts != 1 else ''}"
        if self.outcome == "resumed":
            return f"{head}; reconnected after a gap of {self.seconds:.1f} s ({tries}), writing segment {self.segment}"
        if self.outcome == "gave up":
            last = f"; the last: {self.last_failure}" if self.last_failure else ""
            return f"{head}; {tries} to reconnect failed over {self.seconds:.1f} s{last}: gave up"
        if self.outcome == "stopped":
            return f"{head}; stopped while reconnecting ({self.seconds:.1f} s, {tries})"
        return f"{head}; not reconnecting (reconnecting is off)"


@dataclass
class VideoReport:
    """What a run did: frames read and written, what was skipped and why, how it ended.

    ``outputs`` lists every file written, segment by segment (each view's file of the
    first segment, then of the second, ...); ``gaps`` every drop of a live input, in
    order: all ``"resumed"`` but the last, which may have ended the run.
    """

    frames_read: int = 0
    frames_written: int = 0
    frames_skipped: int = 0
    problems: list[str] = field(default_factory=list)
    interrupted: bool = False
    seconds: float = 0.0
    outputs: list[Path] = field(default_factory=list)
    audio: bool = False
    segments: int = 0
    gaps: list[Gap] = field(default_factory=list)

    @property
    def gave_up(self) -> bool:
        """True when the run ended because a live input could not be reconnected."""
        return bool(self.gaps) and self.gaps[-1].outcome == "gave up"
