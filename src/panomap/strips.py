"""Work on an image's rows in horizontal strips, one per OpenCV thread, at once.

A map is built in a few passes over arrays: NumPy's run on one core, OpenCV's
``remap`` on all of them. Cutting the rows into as many strips as OpenCV has
threads (``cv2.getNumThreads()``, which ``cv2.setNumThreads`` and the video
pipeline's thread budget set) and running every pass of a strip in its own
thread puts the NumPy passes on every core too; both release the GIL. With one
OpenCV thread the work runs in the caller's thread, as one strip.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

import cv2

# Strips are at least this many rows (fewer strips for small images: a thread hand-off costs ~50 us).
MIN_ROWS = 32
# At most this many strips, however many threads OpenCV has.
MAX_STRIPS = 16

_POOL: ThreadPoolExecutor | None = None
_POOL_LOCK = threading.Lock()


def strip_bounds(height: int, count: int) -> list[tuple[int, int]]:
    """``count`` (at most ``height``) row ranges [start, stop) covering ``range(height)`` in order, sizes within 1."""
    count = max(1, min(count, height))
    edges = [round(k * height / count) for k in range(count + 1)]
    return [(edges[k], edges[k + 1]) for k in range(count)]


def strip_count(height: int) -> int:
    """How many strips :func:`in_strips` cuts ``height`` rows into: OpenCV's threads, strips of ``MIN_ROWS`` or more."""
    return max(1, min(cv2.getNumThreads(), MAX_STRIPS, height // MIN_ROWS))


def in_strips(height: int, work: Callable[[int, int], None]) -> None:
    """Call ``work(start, stop)`` on the strips of ``range(height)``, at once, and wait for all.

    The first strip runs in the caller's thread. ``work`` must touch only its
    own rows of shared outputs. The first exception raised is raised here,
    after every strip has finished.
    """
    bounds = strip_bounds(height, strip_count(height))
    if len(bounds) == 1:
        work(*bounds[0])
        return
    futures = [_pool().submit(work, start, stop) for start, stop in bounds[1:]]
    error: BaseException | None = None
    try:
        work(*bounds[0])
    except BaseException as caught:
        error = caught
    for future in futures:
        try:
            future.result()
        except BaseException as caught:
            error = error or caught
    if error is not None:
        raise error


def _pool() -> ThreadPoolExecutor:
    """The process's strip threads (made on first use, again in a forked child)."""
    global _POOL
    with _POOL_LOCK:
        if _POOL is None:
            _POOL = ThreadPoolExecutor(max_workers=MAX_STRIPS - 1, thread_name_prefix="panomap-strip")
        return _POOL


def _forget_pool() -> None:
    """In a forked child, the parent's threads do not exist: make a new pool when needed."""
    global _POOL, _POOL_LOCK
    _POOL = None
    _POOL_LOCK = threading.Lock()


os.register_at_fork(after_in_child=_forget_pool)
