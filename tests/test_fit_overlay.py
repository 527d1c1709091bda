"""`panomap fit --overlay`: the fit drawn on the omni-image, where the true camera sees it.

Ground truth: ``panomap.simulate.TiltedCamera`` (a simulated camera whose axes are turned by
``mount_rotation``); the horizon drawn must run where it projects the world's horizon.
"""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from panomap.calibrate.landmarks.pairs import Landmarks, landmarks_to_csv
from panomap.geometry import ray_from_angles
from panomap.io.overlay import HORIZON, OUTLIER, residual_magnification
from panomap.simulate.cameras import TiltedCamera, mount_rotation, standard_cameras

from helpers import assert_one_line_error, run, spread_landmarks

POSITION = (3.0, 2.0, 2.5)
TILT_DEG, TOWARD_DEG = 3.0, 50.0
# A pixel drawn in a colour counts within this distance of it (BGR): anti-aliased edges blend.
COLOUR_TOLERANCE = 40


def _drawn_near(image: np.ndarray, pixels: np.ndarray, colour: tuple[int, int, int], reach: int = 1) -> np.ndarray:
    """Whether each pixel (n, 2) has ``colour`` within ``reach`` px of it in ``image`` (H, W, 3)."""
    height, width = image.shape[:2]
    found = np.zeros(len(pixels), dtype=bool)
    for k, (u, v) in enumerate(np.round(pixels).astype(int)):
        window = image[max(v - reach, 0) : min(v + reach + 1, height), max(u - reach, 0) : min(u + reach + 1, width)]
        distance = np.abs(window.astype(int) - np.array(colour)).sum(axis=-1)
        found[k] = window.size > 0 and bool(np.any(distance <= COLOUR_TOLERANCE))
    return found


@pytest.fixture(scope="module")
def drawn(tmp_path_factory: pytest.TempPathFactory) -> tuple[TiltedCamera, np.ndarray, str]:
    """A fisheye tilted 3 deg, 20 exact landmarks (one moved 40 px), fitted with `fit --overlay`: the camera,
    the overlay and the command's output."""
    folder = tmp_path_factory.mktemp("overlay")
    base = standard_cameras(seed=3)["equidistant"]
    camera = TiltedCamera(base, mount_rotation(math.radians(TILT_DEG), math.radians(TOWARD_DEG)))
    landmarks = spread_landmarks(camera, POSITION, 20, np.random.default_rng(5))
    pixels = landmarks.pixels.copy()
    pixels[7] += (40.0, 0.0)
    (folder / "lm.csv").write_text(landmarks_to_csv(Landmarks(pixels, landmarks.world, landmarks.names)))
    width, height = base.image_size
    cv2.imwrite(str(folder / "omni.png"), np.full((height, width, 3), 90, np.uint8))
    result = run(
        "fit",
        folder / "lm.csv",
        "-o",
        folder / "cam.npz",
        "--camera",
        *POSITION,
        "--image",
        folder / "omni.png",
        "--centre",
        *base.centre,
        "--outer-radius",
        base.outer_radius,
        "--cutoff-radius",
        0,
        "--overlay",
        folder / "fit.png",
    )
    assert result.exit_code == 0, result.output + result.stderr
    overlay = cv2.imread(str(folder / "fit.png"))
    return camera, overlay, result.output


def test_the_horizon_is_drawn_where_the_tilted_camera_sees_it(drawn: tuple[TiltedCamera, np.ndarray, str]) -> None:
    camera, overlay, _ = drawn
    theta = np.radians(np.arange(0.0, 360.0, 2.0))
    truth = camera.project(ray_from_angles(theta, np.zeros_like(theta)))
    seen = np.all(np.isfinite(truth), axis=1) & (truth[:, 1] > 150)  # (below the legend's lines)
    assert seen.sum() > 100
    hit = _drawn_near(overlay, truth[seen], HORIZON)
    # The fitted horizon within a pixel or so of the true one, all round (a label may cover a few).
    assert hit.mean() >= 0.95, f"{hit.mean():.2f}"
    # Control: the horizon of the camera tilted the other way (30 px off at the horizon) is not what was drawn.
    base = standard_cameras(seed=3)["equidistant"]
    other = TiltedCamera(base, mount_rotation(math.radians(TILT_DEG), math.radians(TOWARD_DEG + 180)))
    wrong = other.project(ray_from_angles(theta, np.zeros_like(theta)))
    keep = np.all(np.isfinite(wrong), axis=1) & (wrong[:, 1] > 150)
    assert _drawn_near(overlay, wrong[keep], HORIZON).mean() < 0.5


def test_the_outlier_is_drawn_red_at_its_pixel_and_named(drawn: tuple[TiltedCamera, np.ndarray, str]) -> None:
    camera, overlay, output = drawn
    assert "outliers dropped: L8" in output
    landmarks = spread_landmarks(camera, POSITION, 20, np.random.default_rng(5))
    moved = landmarks.pixels[7] + (40.0, 0.0)
    # Its circle (radius 5 line widths) in red around the moved pixel; its line to where the fit puts it.
    thickness = max(1, round(min(overlay.shape[:2]) / 500))
    ring = moved + 5 * thickness * np.array([[1.0, 0.0], [0.0, 1.0], [0.0, -1.0]])
    assert _drawn_near(overlay, ring, OUTLIER).all()
    halfway = moved - (20.0, 0.0)
    assert _drawn_near(overlay, halfway[None], OUTLIER).all()


def test_the_residuals_are_magnified_to_be_seen_but_stay_small() -> None:
    # 4% of a 1000 px side is 40 px: 0.5 px drawn x50 (25 px), not x100 (50 px).
    assert residual_magnification(0.5, 1000) == 50
    assert residual_magnification(3.0, 1000) == 10
    assert residual_magnification(0.0, 1000) == 100
    assert residual_magnification(45.0, 1000) == 1


def test_an_overlay_needs_the_image_and_png(tmp_path: Path) -> None:
    (tmp_path / "lm.csv").write_text("u,v,X,Y,Z\n" + "1,2,3,4,0\n" * 6)
    common = ["fit", tmp_path / "lm.csv", "-o", tmp_path / "t.npz", "--camera", *POSITION, "--centre", 1, 1]
    no_image = run(*common, "--overlay", tmp_path / "o.png")
    assert_one_line_error(no_image, "--overlay draws the fit on --image: give --image OMNI too", exit_code=2)
    cv2.imwrite(str(tmp_path / "omni.png"), np.zeros((20, 20, 3), np.uint8))
    jpeg = run(*common, "--image", tmp_path / "omni.png", "--overlay", tmp_path / "o.jpg")
    assert_one_line_error(jpeg, "the overlay is written as PNG", exit_code=2)
    assert not (tmp_path / "t.npz").exists()
