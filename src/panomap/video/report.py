"""What a run of :func:`panomap.video.unwarp.unwarp_video` did."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path


@dataclass
class VideoReport:
    """What a run did: frames read and written, what was skipped and why, how it ended."""

    frames_read: int = 0
    frames_written: int = 0
    frames_skipped: int = 0
    problems: list[str] = field(default_factory=list)
    interrupted: bool = False
    seconds: float = 0.0
    outputs: list[Path] = field(default_factory=list)
    audio: bool = False
