"""Threads hand frames and packets through bounded queues; errors are named in a few words."""

from __future__ import annotations

import queue
from collections.abc import Callable
from typing import Any

# Frames each queue holds: memory stays flat however long the input.
QUEUE_FRAMES = 4
# Put on a queue after the last item.
END = object()


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
