"""The progress bar of the long commands, on a real pseudo-terminal."""

from __future__ import annotations

import fcntl
import os
import pty
import select
import struct
import subprocess
import sys
import termios

import pytest

from panomap.cli.progress import FALLBACK_COLUMNS, ProgressBar, terminal_columns


def _terminal(columns: int, rows: int = 24) -> tuple[int, int]:
    leader, follower = pty.openpty()
    fcntl.ioctl(follower, termios.TIOCSWINSZ, struct.pack("HHHH", rows, columns, 0, 0))
    return leader, follower


def _drawn(columns: int, rows: int = 24) -> str:
    leader, follower = _terminal(columns, rows)
    with os.fdopen(follower, "w", encoding="utf-8", closefd=True) as stream:
        assert terminal_columns(stream) == (columns or None)
        bar = ProgressBar(True, stream)
        bar.update(30, 120)
        bar.write("note: \x1b[2J a name")
        bar.update(60, 120)
        bar.close()
        stream.flush()
    chunks = []
    while select.select([leader], [], [], 0.5)[0]:  # (a pty hands its buffer over in pieces)
        try:
            chunk = os.read(leader, 65536)
        except OSError:  # (EIO: the other side closed and all was read)
            break
        if not chunk:
            break
        chunks.append(chunk)
    os.close(leader)
    return b"".join(chunks).decode("utf-8", "replace")


def test_a_terminal_reporting_0_columns_gets_a_bar_of_fixed_width() -> None:
    # tqdm sized its bar by the terminal's width: 0 columns drew an empty line.
    text = _drawn(0)
    lines = [line for line in text.replace("\r", "\n").split("\n") if "60/120" in line]
    assert lines, text
    assert 0.9 * FALLBACK_COLUMNS <= len(lines[-1]) <= FALLBACK_COLUMNS
    assert "50%" in lines[-1]


def test_a_terminal_reporting_no_size_at_all_gets_the_bar_and_the_stage_lines() -> None:
    """A pty given no size (0 x 0: ``script``, ``docker exec -t``, some CI runners) as stderr: tqdm, reading 0 rows
    there, drew nothing at all, bar or stage line (``rig learn --side-by-side`` was silent for its 14-25 s)."""
    leader, follower = _terminal(0, 0)
    code = (
        "from panomap.cli.progress import ProgressBar\n"
        "bar = ProgressBar(True, unit='step')\n"
        "bar.stage('learning lens 0')\n"
        "bar.update(60, 120)\n"
        "bar.close()\n"
    )
    with subprocess.Popen([sys.executable, "-c", code], stdin=follower, stdout=follower, stderr=follower) as child:
        os.close(follower)
        text = _read_all(leader, child)
    assert "learning lens 0: 00:00" in text, text
    lines = [line for line in text.replace("\r", "\n").split("\n") if "60/120" in line]
    assert lines and "50%" in lines[-1], text


def test_a_terminal_of_known_width_gets_a_bar_that_fills_it_and_messages_are_escaped() -> None:
    text = _drawn(132)
    lines = [line for line in text.replace("\r", "\n").split("\n") if "60/120" in line]
    assert lines and 0.9 * 132 <= len(lines[-1]) <= 132, text
    assert "note: \\x1b[2J a name" in text and "\x1b[2J" not in text


def _read_all(leader: int, child: subprocess.Popen[bytes] | None = None) -> str:
    chunks = []
    while select.select([leader], [], [], 0.5)[0] or (child is not None and child.poll() is None):
        try:
            chunk = os.read(leader, 65536)
        except OSError:
            break
        if not chunk:
            break
        chunks.append(chunk)
    os.close(leader)
    return b"".join(chunks).decode("utf-8", "replace")


@pytest.mark.slow
def test_a_stage_without_a_count_gets_a_line_whose_seconds_tick() -> None:
    """Issue 53: a step with no count (a landmark fit) left the terminal silent; its line now ticks each second."""
    import time

    leader, follower = _terminal(100)
    with os.fdopen(follower, "w", encoding="utf-8", closefd=True) as stream:
        bar = ProgressBar(True, stream)
        bar.stage("fitting the camera")
        time.sleep(2.3)  # two ticks (TICK_S = 1 s), with room for a slow machine
        bar.stage("writing the table")
        bar.close()
        stream.flush()
    text = _read_all(leader)
    drawn = [line for line in text.replace("\r", "\n").split("\n") if line.strip()]
    assert "fitting the camera: 00:02" in drawn, text
    assert drawn[-1] == "writing the table: 00:00", text


def test_a_bar_not_enabled_draws_nothing_and_writes_messages_as_lines(capsys) -> None:  # type: ignore[no-untyped-def]
    bar = ProgressBar(False)
    bar.stage("fitting")
    bar.update(1, 2)
    bar.write("note: a")
    bar.close()
    captured = capsys.readouterr()
    assert captured.err == "note: a\n" and captured.out == ""
