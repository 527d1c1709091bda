"""The encoder's stderr kept while it opens: descriptor 2 put back as it was, whatever the threads."""

from __future__ import annotations

import os
import threading

from panomap.video.encoder_open import _stderr_kept


def _identity(fd: int) -> tuple[int, int]:
    status = os.fstat(fd)
    return status.st_dev, status.st_ino


def test_two_threads_leave_descriptor_2_as_it_was() -> None:
    """A second thread that keeps stderr while the first does must not leave descriptor 2 on the first's sink."""
    before, saved = _identity(2), os.dup(2)
    entered, second_in, first_out = threading.Event(), threading.Event(), threading.Event()

    def first() -> None:  # in first, out first
        with _stderr_kept():
            entered.set()
            second_in.wait(timeout=0.5)  # (the second is let in at once where nothing holds it out)
        first_out.set()

    def second() -> None:  # in second, out last
        entered.wait()
        with _stderr_kept():
            second_in.set()
            first_out.wait(timeout=5)

    try:
        threads = [threading.Thread(target=first), threading.Thread(target=second)]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
        assert _identity(2) == before
    finally:
        os.dup2(saved, 2)
        os.close(saved)


def test_kept_lines_are_those_written_to_descriptor_2() -> None:
    with _stderr_kept() as said:
        os.write(2, b"x264 [error]: invalid preset 'nope'\n")
    assert said == ["x264 [error]: invalid preset 'nope'"]
