"""Rows cut into strips, one per OpenCV thread, made at once: every row once, errors raised, results
independent of the number of threads. Tries run two at a time (``Ahead``): each result in order, errors
raised where asked for, nothing left running."""

from __future__ import annotations

import itertools
import threading
import time

import cv2
import numpy as np
import pytest

from panomap.strips import MIN_ROWS, Ahead, in_strips, strip_bounds, strip_count


@pytest.fixture
def opencv_threads():
    """Set OpenCV's thread count for a test; restored after it."""
    before = cv2.getNumThreads()
    yield cv2.setNumThreads
    cv2.setNumThreads(before)


@pytest.mark.parametrize("height, count", [(1, 1), (7, 3), (720, 2), (721, 16), (5, 9)])
def test_strip_bounds_cover_every_row_once_in_order(height: int, count: int) -> None:
    bounds = strip_bounds(height, count)
    assert len(bounds) == min(count, height)
    assert bounds[0][0] == 0 and bounds[-1][1] == height
    assert all(stop == start for (_, stop), (start, _) in itertools.pairwise(bounds))
    sizes = [stop - start for start, stop in bounds]
    assert max(sizes) - min(sizes) <= 1


def test_strips_follow_opencv_threads(opencv_threads) -> None:
    opencv_threads(4)
    assert strip_count(720) == 4
    assert strip_count(3 * MIN_ROWS) == 3  # no strip under MIN_ROWS rows
    opencv_threads(1)
    assert strip_count(720) == 1


def test_in_strips_runs_every_row_once_in_several_threads(opencv_threads) -> None:
    opencv_threads(4)
    seen = np.zeros(1000, dtype=int)
    threads = set()
    together = threading.Barrier(4, timeout=30)  # broken unless the four strips run at once

    def work(start: int, stop: int) -> None:
        threads.add(threading.get_ident())
        together.wait()
        seen[start:stop] += 1

    in_strips(1000, work)
    assert np.all(seen == 1)
    assert len(threads) == 4 and threading.get_ident() in threads


def test_in_strips_raises_a_strips_error_after_all_strips_finish(opencv_threads) -> None:
    opencv_threads(3)
    finished = []

    def work(start: int, stop: int) -> None:
        finished.append(start)
        if start == 100:  # the second of three strips, in a strip thread
            raise ValueError(f"strip at {start}")

    with pytest.raises(ValueError, match="strip at"):
        in_strips(300, work)
    assert len(finished) == 3


def test_ahead_runs_two_tries_at_once_and_gives_each_result_or_error(opencv_threads) -> None:
    opencv_threads(2)
    together = threading.Barrier(2, timeout=30)  # broken unless tries 0 and 1 run at once
    started, ended = [], []

    def work(item: int) -> int:
        started.append(item)
        if item < 2:
            together.wait()
        time.sleep(0.05 * (item == 5))
        ended.append(item)
        if item == 2:
            raise ValueError("try 2")
        return 10 * item

    with Ahead(work, [0, 1, 2, 3, 4, 5]) as tries:
        assert tries.result(0) == 0
        assert tries.result(1) == 10
        with pytest.raises(ValueError, match="try 2"):
            tries.result(2)
        assert tries.result(4) == 40  # 3 is skipped: it was started beside 2, and is waited for on exit
    assert {0, 1, 2, 3, 4} <= set(started) <= {0, 1, 2, 3, 4, 5}  # 5 is started beside 4 (or cancelled)
    assert sorted(ended) == sorted(started)  # nothing still running after the block


def test_ahead_with_one_opencv_thread_runs_each_try_in_the_caller_only_when_asked(opencv_threads) -> None:
    opencv_threads(1)
    threads = []

    def work(item: int) -> int:
        threads.append(threading.get_ident())
        return item + 1

    with Ahead(work, [1, 2, 3]) as tries:
        assert tries.result(0) == 2
        assert tries.result(2) == 4
    assert threads == [threading.get_ident()] * 2
