"""Work on an image's rows in horizontal strips, one per OpenCV thread, at once.

A map is built in a few passes over arrays: NumPy's run on one core, OpenCV's
``remap`` on all of them. Cutting the rows into as many strips as OpenCV has
threads (``cv2.getNumThreads()``, which ``cv2.setNumThreads`` and the video
pipeline's thread budget set) and running every pass of a strip in its own
thread puts the NumPy passes on every core too; both release the GIL. With one
OpenCV thread the work runs in the caller's thread, as one strip.

:class:`Ahead` uses the same threads for a list of independent tries (candidate
circles, say) that are read in order and usually all needed: the next try runs
in a strip thread while the caller works on the current one.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Generic, TypeVar

import cv2

# Strips are at least this many rows (fewer strips for small images: a thread hand-off costs ~50 us).
MIN_ROWS = 32
# At most this many strips, however many threads OpenCV has.
MAX_STRIPS = 16

Item = TypeVar("Item")
Result = TypeVar("Result")

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


class Ahead(Generic[Item, Result]):
    """``work(item)`` for each of ``items`` on demand, two at a time in strip threads.

    ``result(k)`` returns (or raises) ``work(items[k])``. When OpenCV has more than one
    thread, ``work(items[k])`` and ``work(items[k + 1])`` are started in strip threads
    (unless already) and the first is waited for, so that two tries always run at once;
    with one thread, ``work(items[k])`` runs in the caller's. An item never asked for
    costs at most one wasted try. Use it as a context manager: on exit it waits for a try
    still running, so that no work outlives the caller. ``work`` must be safe to run in
    another thread (pure array work is).
    """

    def __init__(self, work: Callable[[Item], Result], items: Sequence[Item]) -> None:
        self._work = work
        self._items = items
        self._started: dict[int, Future[Result]] = {}
        self._ahead = cv2.getNumThreads() > 1

    def result(self, index: int) -> Result:
        """``work(items[index])``: its exception, if it raised one, is raised here."""
        if self._ahead:
            for start in (index, index + 1):
                if start < len(self._items) and start not in self._started:
                    self._started[start] = _pool().submit(self._work, self._items[start])
        started = self._started.pop(index, None)
        return started.result() if started is not None else self._work(self._items[index])

    def __enter__(self) -> Ahead[Item, Result]:
        return self

    def __exit__(self, *exc: object) -> None:
        for started in self._started.values():
            if not started.cancel():
                started.exception()  # wait; its result is not wanted
        self._started.clear()


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
