"""What a view of a rig says it wrote: how much of the view is seen, how much is blended, and each ``--each`` file.

It once said "100% of pixels seen by 2 cameras" of every view, whether one camera or both saw a pixel, and wrote
the ``--each`` files without naming them. Ground truth: two ideal lenses back to back, each seeing ``FOV_DEG / 2``
off its axis (+X and -X): every direction is seen (closed form: each is within 90 deg of one axis), and no
pixel can be blended where the two do not both see it (within ``FOV_DEG / 2`` of both axes).
"""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from panomap.interop.rig_of_camchain import rig_of_camchain
from panomap.rig import save_rig

from helpers import run

FOV_DEG, SIDE, F_PX = 200.0, 320, 90.0
POSE = "[[-1, 0, 0, 0], [0, 1, 0, 0], [0, 0, -1, -0.02], [0, 0, 0, 1]]"


def dual_rig(tmp_path: Path, pose: str = POSE) -> Path:
    centre = SIDE / 2 - 0.5
    lens = (
        f"camera_model: pinhole, intrinsics: [{F_PX}, {F_PX}, {centre}, {centre}], distortion_model: equidistant, "
        f"distortion_coeffs: [0, 0, 0, 0], resolution: [{SIDE}, {SIDE}]"
    )
    (tmp_path / "dual.yaml").write_text(f"cam0: {{{lens}}}\ncam1: {{{lens}, T_cn_cnm1: {pose}}}\n")
    rig = rig_of_camchain(tmp_path / "dual.yaml", side_by_side=True, fov_rad=math.radians(FOV_DEG))
    save_rig(rig, tmp_path / "dual.npz")
    return tmp_path / "dual.npz"


def both_see_share(width: int, height: int) -> float:
    """The share of an equirectangular view's pixels within FOV_DEG / 2 of both +X and -X (closed form)."""
    lon = (np.arange(width) + 0.5) / width * 2 * np.pi - np.pi
    lat = np.pi / 2 - (np.arange(height) + 0.5) / height * np.pi
    off_deg = np.degrees(np.arccos(np.cos(lat)[:, None] * np.cos(lon)[None, :]))
    return float(np.mean(np.abs(off_deg - 90.0) < FOV_DEG / 2 - 90.0))


def test_a_rig_view_says_what_is_seen_and_blended_and_names_each_file(tmp_path: Path) -> None:
    rig = dual_rig(tmp_path)
    frame = np.random.default_rng(3).integers(0, 255, (SIDE, 2 * SIDE, 3), dtype=np.uint8)
    cv2.imwrite(str(tmp_path / "frame.png"), frame)
    result = run("equirect", rig, tmp_path / "frame.png", "-o", tmp_path / "pano.png", "--size", "400x200",
                 "--each", str(tmp_path / "lens_{camera}.png"))  # fmt: skip
    assert result.exit_code == 0, result.output + result.stderr
    first, second = result.stdout.splitlines()
    assert first.startswith(f"wrote {tmp_path / 'pano.png'} (400 x 200: 100% seen, "), first
    blended = float(first.split("seen, ")[1].split("%")[0])
    assert 0 < blended <= 100 * both_see_share(400, 200) + 0.5, (first, both_see_share(400, 200))
    assert second == f"wrote each camera's own view: {tmp_path / 'lens_cam0.png'}, {tmp_path / 'lens_cam1.png'}"
    assert all((tmp_path / f"lens_cam{k}.png").exists() for k in (0, 1))


def test_a_view_one_camera_sees_blends_nothing(tmp_path: Path) -> None:
    """A perspective view along camera 0's axis, 90 deg across, lies within 45 deg of +X: camera 1 (-X, seeing
    100 deg off its axis) sees none of it, so nothing is blended."""
    rig = dual_rig(tmp_path)
    cv2.imwrite(str(tmp_path / "frame.png"), np.full((SIDE, 2 * SIDE, 3), 90, np.uint8))
    result = run("perspective", rig, tmp_path / "frame.png", "-o", tmp_path / "v.png", "--size", "160x90")
    assert result.exit_code == 0, result.output + result.stderr
    assert ": 100% seen, 0% blended from two cameras or more;" in result.stdout, result.stdout


@pytest.mark.parametrize(("apart", "noted"), [(-0.02, False), (0.0, True)])
def test_distance_at_one_point_says_it_changes_nothing(tmp_path: Path, apart: float, noted: bool) -> None:
    """--distance moves each camera's rays to its own position: with the lenses at one point (a camchain's t of 0,
    as a hand-tuned dual-fisheye model has) it changes nothing, and a note says so rather than nothing."""
    rig = dual_rig(tmp_path, POSE.replace("-0.02", str(apart)))
    cv2.imwrite(str(tmp_path / "frame.png"), np.full((SIDE, 2 * SIDE, 3), 90, np.uint8))
    result = run("equirect", rig, tmp_path / "frame.png", "-o", tmp_path / "v.png", "--size", "200x100",
                 "--distance", "0.5")  # fmt: skip
    assert result.exit_code == 0, result.output + result.stderr
    notes = [line for line in result.stderr.splitlines() if "--distance changes nothing here" in line]
    assert len(notes) == int(noted), result.stderr
    assert all(len(line) <= 160 for line in notes)


def test_a_rig_of_one_camera_reads_as_one(tmp_path: Path) -> None:
    """A rig of one camera (the doc's floor-landmark example) is "a rig of 1 camera", and its view blends nothing."""
    centre = SIDE / 2 - 0.5
    (tmp_path / "one.yaml").write_text(
        f"cam0: {{camera_model: pinhole, intrinsics: [{F_PX}, {F_PX}, {centre}, {centre}], distortion_model: "
        f"equidistant, distortion_coeffs: [0, 0, 0, 0], resolution: [{SIDE}, {SIDE}]}}\n"
    )
    assert run("import", tmp_path / "one.yaml", "-o", tmp_path / "t.npz", "--orientation", "0", "0", "0").exit_code == 0
    made = run("rig", "make", tmp_path / "t.npz", "-o", tmp_path / "one.npz")
    assert made.exit_code == 0 and made.stdout.splitlines()[0] == "rig of 1 camera", made.stdout
    cv2.imwrite(str(tmp_path / "frame.png"), np.full((SIDE, SIDE, 3), 90, np.uint8))
    result = run("equirect", tmp_path / "one.npz", tmp_path / "frame.png", "-o", tmp_path / "v.png", "--size", "20x10")
    assert result.exit_code == 0, result.output + result.stderr
    assert "blended" not in result.stdout and "; gains t x1.000)" in result.stdout, result.stdout


def test_report_lines_fold_after_a_semicolon_within_160_characters() -> None:
    """rig learn's and rig place's report lines ran to 250 characters: each is cut after a '; ' where it runs
    past 160, the pieces indented, nothing lost."""
    from panomap.cli.rigs import fold_line

    line = "  " + "; ".join(f"part {k} " + "x" * 40 for k in range(9))
    folded = fold_line(line)
    assert len(folded) > 1 and all(len(piece) <= 160 for piece in folded), folded
    assert folded[0].startswith("  part 0") and all(piece.startswith("    part") for piece in folded[1:])
    assert " ".join(piece.strip() for piece in folded) == line.strip()
    assert fold_line("short; line") == ["short; line"]
    assert fold_line("y" * 200) == ["y" * 200]  # nowhere to cut: whole
