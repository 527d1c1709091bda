"""What the libraries write to the process's stderr themselves, kept: their words become a reason, not a
second line on the terminal (an encoder's refusal, :mod:`panomap.video.encoder_open`; libjpeg's and libpng's
complaints while OpenCV decodes, :func:`panomap.io.images.read_image`)."""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile
import threading
from collections.abc import Iterator

# At most this much of what a library writes to stderr while it opens is read back.
MAX_SAID_BYTES = 64_000

# Descriptor 2 (and, for encoders, FFmpeg's log level) are the process's: one block at a time (two threads'
# interleaved would leave descriptor 2 on a sink).
STDERR_LOCK = threading.RLock()


@contextlib.contextmanager
def stderr_kept() -> Iterator[list[str]]:
    """The lines written to file descriptor 2 while the block runs (by any code of this process), in the list
    yielded, filled when the block ends. Where descriptor 2 cannot be duplicated, nothing is kept. One thread at a
    time: another waits for the first to put descriptor 2 back."""
    said: list[str] = []
    with STDERR_LOCK:
        if sys.stderr is not None:  # (None without a console)
            sys.stderr.flush()
        try:
            saved = os.dup(2)
        except OSError:
            yield said
            return
        with tempfile.TemporaryFile() as sink:
            os.dup2(sink.fileno(), 2)
            try:
                yield said
            finally:
                os.dup2(saved, 2)
                os.close(saved)
                sink.seek(0)
                said.extend(sink.read(MAX_SAID_BYTES).decode("utf-8", "replace").splitlines())
