"""A view command names every required option it lacks in one line: a floor map needs --z, --x and --y, and a
user told of them one at a time ran it three times to learn them (walk 63)."""

from __future__ import annotations

from pathlib import Path

import pytest

from helpers import assert_one_line_error, run


@pytest.mark.parametrize(
    ("kind", "given", "missing"),
    [
        ("floor", [], ["--z", "--x XMIN XMAX", "--y YMIN YMAX"]),
        ("cylinder", ["--size", "200x100"], ["--distance", "--band ZB ZT"]),
        ("plane", ["--distance", "2"], ["--width", "--band ZB ZT", "--azimuth DEG", "--size WxH"]),
    ],
)
def test_every_missing_option_is_named_at_once(tmp_path: Path, kind: str, given: list[str], missing: list[str]) -> None:
    result = run(kind, tmp_path / "cam.npz", tmp_path / "omni.png", "-o", tmp_path / "out.png", *given)
    assert_one_line_error(result, f"missing options: {', '.join(missing)}", exit_code=2)
    assert not (tmp_path / "out.png").exists()


def test_one_missing_option_and_a_missing_argument_read_as_before(tmp_path: Path) -> None:
    result = run("floor", tmp_path / "cam.npz", tmp_path / "omni.png", "-o", tmp_path / "o.png", "--z", 0, "--x", 0, 1)
    assert_one_line_error(result, "Missing option '--y'", exit_code=2)
    assert_one_line_error(run("floor"), "Missing argument 'TABLE'", exit_code=2)
    assert run("floor", "--help").exit_code == 0
