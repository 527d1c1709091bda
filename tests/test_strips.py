"""Rows cut into strips, one per OpenCV thread, made at once: every row once, errors raised, results
independent of the number of threads."""

from __future__ import annotations

import itertools
import threading

import cv2
import numpy as np
import pytest

from panomap.strips import MIN_ROWS, in_strips, strip_bounds, strip_count


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
