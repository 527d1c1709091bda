"""Threads hand frames and packets through bounded queues; errors are named in a few words."""

from __future__ import annotations

import queue
from collections.abc import Callable
from typing import Any

# Frames each queue holds: memory stays flat however long the input.
QUEUE_FRAMES = 4
# Put on a queue after the last item.
END = object()
# A reader may decode this many bytes of frames ahead (each of a run's inputs together), and at most this many
# frames: while a rig's view builds its maps and weights (0.5-1 s, mostly on one core) the decoder works on the
# other core instead of stopping after QUEUE_FRAMES, and those frames are not decoded later beside the encoder.
AHEAD_BYTES = 256 * 2**20
AHEAD_FRAMES = 32


def frames_ahead(frame_bytes: int, machine_bytes: int | None = None) -> int:
    """How many frames of ``frame_bytes`` (every input's frame at one time, in bytes) a reader's queue holds:
    as many as :data:`AHEAD_BYTES` (or 1/32 of ``machine_bytes``, the machine's memory, where less) takes, at
    most :data:`AHEAD_FRAMES`, at least :data:`QUEUE_FRAMES`."""
    budget = AHEAD_BYTES if machine_bytes is None else min(AHEAD_BYTES, machine_bytes // 32)
    return max(QUEUE_FRAMES, min(AHEAD_FRAMES, budget // max(1, frame_bytes)))


def put(box: queue.Queue[Any], item: Any, give_up: Callable[[], bool]) -> bool:
    """Put ``item`` on a bounded queue, waiting while it is full unless ``give_up()``; True when put."""
    while True:
        try:
            box.put(item, timeout=0.1)
            return True
        except queue.Full:
            if give_up():
                return False


def reason(exc: BaseException) -> str:
    return " ".join(str(getattr(exc, "strerror", None) or exc).split())
