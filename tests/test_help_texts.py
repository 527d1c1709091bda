"""What ``--help`` tells a new user: every view kind a video takes, and that several cameras make a rig (walk 63:
``video --help`` listed every kind but equirect, and ``panomap --help`` never said a 360 camera is a rig)."""

from __future__ import annotations

from panomap.views import view_kinds

from helpers import run


def test_video_help_shows_a_spec_of_every_view_kind() -> None:
    shown = run("video", "--help").stdout
    for kind, cls in view_kinds().items():
        assert f"{kind}:{cls.example}" in shown, kind


def test_the_main_help_names_rigs_and_their_commands() -> None:
    shown = run("--help").stdout
    assert "a 360 camera" in shown and "--side-by-side" in shown and "rig make|learn|place" in shown
    assert max(len(line) for line in shown.splitlines()) <= 100
