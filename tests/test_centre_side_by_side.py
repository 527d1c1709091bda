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
    u0 = float(result.stdout.split()[1])
    half = "left" if u0 < 400 else "right"
    assert f"this is the {half} lens of a frame of two side by side" in result.stdout
    single = tmp_path / "single.png"
    cv2.imwrite(str(single), frame[:, :400].copy())
    result = run("centre", single)
    assert result.exit_code == 0 and "side by side" not in result.stdout, result.stdout + result.stderr
