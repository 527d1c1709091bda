"""A dual fisheye learned from its own frames, no calibration (``panomap rig learn --side-by-side``,
:func:`panomap.calibrate.dual_fisheye.learn_dual_fisheye`): refused in one line where its frames cannot pin it.

Ground truth: frames rendered in closed form by bench/bench_dual_learn.py (two equidistant lenses, back to back but
for a small turn, either stretched along their axes: ``S d / |S d|``) from the line scenes' room, and from a real 360
photograph (skipped where ../shared is absent)."""

from __future__ import annotations

import importlib.util
import math
import sys
from pathlib import Path
from types import ModuleType

import cv2
import numpy as np
import pytest

from panomap.calibrate.dual_fisheye import learn_dual_fisheye, split_frame
from panomap.errors import PanomapError

from helpers import run

PHOTOGRAPH = Path(__file__).resolve().parents[2] / "shared" / "data" / "panoramas" / "eso_alma_correlator_room.jpg"
#: The whole refusal on stderr, prefix and hint included, at most this long (one line a user reads).
LINE_CHARS = 160


def _bench() -> ModuleType:
    path = Path(__file__).resolve().parents[1] / "bench" / "bench_dual_learn.py"
    spec = importlib.util.spec_from_file_location("bench_dual_learn", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["bench_dual_learn"] = module  # dataclasses look their module up while the file runs
    spec.loader.exec_module(module)
    return module


def test_a_frame_splits_into_its_two_halves_lens_0_on_the_left() -> None:
    """Halves of one size, the left one first; an odd width is refused (no two lenses of one size)."""
    frame = np.arange(4 * 6 * 3, dtype=np.uint8).reshape(4, 6, 3)
    left, right = split_frame(frame)
    assert np.array_equal(left, frame[:, :3]) and np.array_equal(right, frame[:, 3:])
    with pytest.raises(PanomapError, match="7 px wide"):
        split_frame(np.zeros((4, 7), np.uint8))


def test_the_bench_lens_projects_its_own_rays_back_to_their_pixels() -> None:
    """The closed-form lens the frames come from: stretched 6%, its rays land on their pixels (1e-9 px), and a
    pixel 45 deg off the unstretched axis sees ``atan(tan(45 deg) / 1.06)`` (the stretch's closed form)."""
    bench = _bench()
    lens = bench.Lens(stretch=1.06)
    u, v = np.meshgrid(np.linspace(30, 930, 25), np.linspace(30, 930, 25))
    rays = lens.rays(u, v).reshape(-1, 3)
    ok = np.isfinite(rays).all(axis=1)
    back = lens.project(rays[ok])
    assert np.abs(back - np.stack([u.ravel(), v.ravel()], axis=1)[ok]).max() < 1e-9
    ray = lens.rays(np.array([lens.cx + lens.f * math.pi / 4]), np.array([lens.cy]))[0]
    assert math.degrees(math.acos(ray[2])) == pytest.approx(math.degrees(math.atan(1 / 1.06)), abs=1e-9)


def _frames(case_index: int) -> list[np.ndarray]:  # type: ignore[type-arg]
    bench = _bench()
    case = bench.CASES[case_index]
    return [bench.render_frame(*bench.case_truth(case, pose), case.scene) for pose in case.poses_deg]


def _assert_refused_in_one_line(frames: list[np.ndarray], tmp_path: Path, *fragments: str) -> None:  # type: ignore[type-arg]
    """``rig learn --side-by-side`` of the frames: exit code 1, one line of at most LINE_CHARS on stderr holding
    each fragment, no file written; ``--verbose`` adds the figures (what the overlap pins and what it does not)."""
    paths = []
    for n, frame in enumerate(frames):
        paths.append(tmp_path / f"frame{n}.png")
        cv2.imwrite(str(paths[-1]), frame)
    out = tmp_path / "rig.npz"
    result = run("rig", "learn", "--side-by-side", *paths, "-o", out)
    assert result.exit_code == 1, result.output + result.stderr
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and len(lines[0]) <= LINE_CHARS, lines
    assert "Traceback" not in result.output + result.stderr
    for fragment in fragments:
        assert fragment in lines[0], lines[0]
    assert not out.exists() and list(tmp_path.iterdir()) == paths
    verbose = run("rig", "learn", "--side-by-side", *paths, "-o", out, "--verbose")
    assert verbose.exit_code == 1 and not out.exists()
    assert "never the stretch common to both lenses along their axis" in verbose.stderr, verbose.stderr


@pytest.mark.slow
def test_two_lenses_stretched_6_percent_along_their_axes_are_refused_and_nothing_is_written(tmp_path: Path) -> None:
    """A level dual fisheye in a room, its axes along the walls, both lenses the equidistant lens stretched 6% along
    their axes: its lines are exactly as straight, and its overlap agrees, for every common stretch, so the lens it
    would otherwise write (the unstretched law explains the frame as well) would be 6% off, tens of px at 45 deg.
    Refused in one line naming the lens, nothing written."""
    bench = _bench()
    assert bench.CASES[1].stretch == 1.06 and bench.CASES[1].poses_deg == ((0.0, 0.0),)
    frames = _frames(1)
    with pytest.raises(PanomapError) as caught:
        learn_dual_fisheye(frames)
    assert caught.value.summary.startswith("lens 0 (left) is not pinned by these frames")
    _assert_refused_in_one_line(frames, tmp_path, "is not pinned by these frames", "panomap fit --image")
