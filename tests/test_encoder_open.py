"""The encoder's stderr kept while it opens: descriptor 2 put back as it was, whatever the threads."""

from __future__ import annotations

import os
import threading
from collections.abc import Callable

from panomap.video.encoder_open import _stderr_kept, open_codec


def _identity(fd: int) -> tuple[int, int]:
    status = os.fstat(fd)
    return status.st_dev, status.st_ino


def run_both(*targets: Callable[[], None]) -> None:
    """Run each of ``targets`` on a thread of its own, all at once, and wait for them all."""
    threads = [threading.Thread(target=target) for target in targets]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()


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
        run_both(first, second)
        assert _identity(2) == before
    finally:
        os.dup2(saved, 2)
        os.close(saved)


def test_kept_lines_are_those_written_to_descriptor_2() -> None:
    with _stderr_kept() as said:
        os.write(2, b"x264 [error]: invalid preset 'nope'\n")
    assert said == ["x264 [error]: invalid preset 'nope'"]


class _Waiting:
    """A codec context whose ``open`` waits on ``until`` (a stand-in for an encoder that takes its time)."""

    def __init__(self, started: threading.Event, until: threading.Event) -> None:
        self.started, self.until = started, until

    def open(self) -> None:
        self.started.set()
        self.until.wait(timeout=0.5)  # (the other thread is let in at once where nothing holds it out)


def test_two_threads_opening_leave_ffmpegs_log_level_as_it_was() -> None:
    """The log level is the process's too: the second opening must not put back the first's ERROR for good."""
    import av.logging

    before = av.logging.get_level()
    av.logging.set_level(av.logging.WARNING)
    first_in, second_in, first_out = threading.Event(), threading.Event(), threading.Event()

    def first() -> None:
        open_codec(_Waiting(first_in, second_in))
        first_out.set()

    def second() -> None:
        first_in.wait()
        open_codec(_Waiting(second_in, first_out))

    try:
        run_both(first, second)
        assert av.logging.get_level() == av.logging.WARNING
    finally:
        av.logging.set_level(before)
