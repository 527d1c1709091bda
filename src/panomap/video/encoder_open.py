"""An encoder opened with what it says kept: the reason it refuses, in its own words, and nothing on the terminal.

FFmpeg's encoders report why they refuse through FFmpeg's log, which PyAV keeps quiet (the exception then says
only "Generic error in an external library"); some libraries also write to the process's stderr themselves,
past that log: x264 a bad preset or tune (``x264 [error]: invalid preset 'nope'``), SVT-AV1 a banner of five
lines at every start. Both are caught here while the encoder opens.
"""

from __future__ import annotations

import re
import sys
from typing import Any

import av
import av.logging

from ..io.stderr_kept import STDERR_LOCK as _STDERR_LOCK
from ..io.stderr_kept import stderr_kept as _stderr_kept

# At most this many of the encoder's lines make its reason (the first say why; the rest, that it failed).
MAX_REASONS = 2

# A library's own prefix to a line ("x264 [error]: ", "Svt[error]: ", "[libx264 @ 0x55d] "), taken off.
_PREFIX = re.compile(r"^(?:\[[^\]]*\]\s*|[\w-]+\s?\[\w+\]:\s*)+")
# Lines of no news: a banner, information.
_INFO = re.compile(r"\[info\]", re.IGNORECASE)


def open_codec(context: Any, echo: bool = True) -> str | None:
    """Open the encoder ``context`` (a PyAV codec context, its size, format and options set).

    Returns None where it opened, else why it did not: the encoder's own words (its log's errors, the lines it
    wrote to stderr), or the exception's where it said none. What an encoder that opens writes to stderr is
    written on where ``echo``, its information lines left out. One thread opens at a time (the log level and
    descriptor 2 are the process's).
    """
    failure: BaseException | None = None
    with _STDERR_LOCK:
        level, skip = av.logging.get_level(), av.logging.get_skip_repeated()
        av.logging.set_level(av.logging.ERROR)
        av.logging.set_skip_repeated(False)  # (a retry's refusal repeats the first's words: they are its reason too)
        try:
            with _stderr_kept() as said, av.logging.Capture() as logged:
                try:
                    context.open()
                except (av.error.FFmpegError, ValueError, TypeError) as exc:
                    failure = exc
        finally:
            av.logging.set_level(level)
            av.logging.set_skip_repeated(skip)
    lines = [line.strip() for line in said if line.strip() and not _INFO.search(line)]
    if failure is None:
        if lines and echo and sys.stderr is not None:
            sys.stderr.write("".join(f"{line}\n" for line in lines))
        return None
    words = [*(_PREFIX.sub("", line) for line in lines), *(str(message).strip() for _, _, message in logged)]
    words = list(dict.fromkeys(word.rstrip(".") for word in words if word))[:MAX_REASONS]
    return "; ".join(words) if words else " ".join(str(getattr(failure, "strerror", None) or failure).split())
