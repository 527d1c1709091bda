"""``panomap centre`` on a dual fisheye's raw frame says which of the two lenses it measured."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from panomap.calibrate.circles.side_by_side import side_by_side_half

from helpers import run


def test_a_circle_centred_in_one_half_of_a_two_to_one_frame_is_that_half() -> None:
    assert side_by_side_half((479.5, 479.5), (1920, 960)) == "left"
    assert side_by_side_half((1439.5, 481.0), (1920, 960)) == "right"
    assert side_by_side_half((520.0, 479.5), (1920, 960)) == "left"  # 40 px off the half's middle: within 96
    assert side_by_side_half((959.5, 479.5), (1920, 960)) is None  # a circle across the middle
    assert side_by_side_half((479.5, 479.5), (1280, 960)) is None  # not two to one
    assert side_by_side_half((479.5, 200.0), (1920, 960)) is None  # far above the middle row


def test_centre_names_the_lens_of_a_dual_frame_and_says_nothing_on_a_single_one(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    frame = cv2.GaussianBlur((120 + 80 * rng.random((400, 800))).astype(np.uint8), (0, 0), 1.5)
    v, u = np.mgrid[0:400, 0:800]
    inside = (np.hypot(u - 199.5, v - 199.5) < 180) | (np.hypot(u - 599.5, v - 199.5) < 180)
    frame[~inside] = 6
    path = tmp_path / "dual.png"
    cv2.imwrite(str(path), frame)
    result = run("centre", path)
    assert result.exit_code == 0, result.stderr
    u0, v0 = map(float, result.stdout.split()[1:3])
    # the circle drawn about (199.5, 199.5) or (599.5, 199.5): found exactly (measured 0.00 px at 2 decimals)
    assert min(abs(u0 - 199.5), abs(u0 - 599.5)) < 0.1 and abs(v0 - 199.5) < 0.1, result.stdout
    half = "left" if u0 < 400 else "right"
    line = next(line for line in result.stdout.splitlines() if "side by side" in line)
    assert line.startswith(f"this is the {half} lens of a frame of two side by side") and len(line) <= 160, line
    single = tmp_path / "single.png"
    cv2.imwrite(str(single), frame[:, :400].copy())
    result = run("centre", single)
    assert result.exit_code == 0 and "side by side" not in result.stdout, result.stdout + result.stderr


def camchain(path: Path, centre: tuple[float, float]) -> Path:
    """An equidistant lens (f 115 px: 180 px at 90 deg) of the 800 x 400 frame, its principal point at ``centre``."""
    path.write_text(
        "cam0:\n  camera_model: pinhole\n"
        f"  intrinsics: [115.0, 115.0, {centre[0]}, {centre[1]}]\n"
        "  distortion_model: equidistant\n  distortion_coeffs: [0.0, 0.0, 0.0, 0.0]\n"
        "  resolution: [800, 400]\n"
    )
    return path


def test_import_with_a_dual_frame_names_the_lens_and_refuses_the_other_ones_circle(tmp_path: Path) -> None:
    """``import --image`` of a single lens's calibration with a dual fisheye's raw frame: where the circle found is
    this lens's, a note names it and points to --side-by-side (as centre does); where it is the other lens's (the
    calibration's principal point in the other half), one line refuses it (before: 'the cut-off radius (0 px) must
    be >= 0 and below the outer radius (-220.0 px)'), and --outer-radius given imports it."""
    rng = np.random.default_rng(1)
    frame = cv2.GaussianBlur((120 + 80 * rng.random((400, 800))).astype(np.uint8), (0, 0), 1.5)
    v, u = np.mgrid[0:400, 0:800]
    frame[(np.hypot(u - 199.5, v - 199.5) >= 180) & (np.hypot(u - 599.5, v - 199.5) >= 180)] = 6
    image = tmp_path / "dual.png"
    cv2.imwrite(str(image), frame)
    found = float(run("centre", image).stdout.split()[1])
    half, other = ("left", "right") if found < 400 else ("right", "left")
    own = camchain(tmp_path / "own.yaml", (found, 199.5))
    result = run("import", own, "-o", tmp_path / "own.npz", "--image", image)
    assert result.exit_code == 0, result.stderr
    assert f"two lenses side by side: the {half} one's circle taken" in result.stderr
    assert "--side-by-side" in result.stderr and "radii 0.0..18" in result.stdout  # the circle's 180 px, within 1 px
    across = camchain(tmp_path / "across.yaml", (800.0 - found, 199.5))
    out = tmp_path / "across.npz"
    result = run("import", across, "-o", out, "--image", image)
    assert result.exit_code == 1 and not out.exists()
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and f"the circle found is the {half} one's, this calibration's the {other} one's" in lines[0]
    assert "--outer-radius" in lines[0] and "--side-by-side" in lines[0]
    assert len(lines[0]) <= len(f"panomap: error: {image}: ") + 160, lines[0]
    assert run("import", across, "-o", out, "--image", image, "--outer-radius", "180").exit_code == 0
