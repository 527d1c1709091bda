"""Imported calibrations of mirror cameras: the world's handedness, and a found image circle beyond the model.

Truth in closed form: a paracatadioptric camera (a parabolic mirror, focus at the origin, opening up, seen
from below by an orthographic camera looking up, image right = world +X, so image down = world +Y). The ray
from world direction d toward the focus meets the mirror at distance 2f / (1 + cos b) along d (b: d's angle
from straight down) and reaches the camera parallel to the axis, so d lands at

    (u, v) = (cx, cy) + g tan(b / 2) (cos theta, sin theta),    theta: d's world azimuth.

Its calibration is the unified (Mei) model with xi = 1 and gamma = g, whose frame ray is (d_X, d_Y, -d_Z): the
world's mirror image, as every central model's frame of a mirror camera is.
"""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np
import pytest
from click.testing import Result

from panomap import import_calibration, load_table

from helpers import run

G, CX, CY = 120.0, 320.0, 240.0


def omnidir_file(path: Path, gamma: float, xi: float) -> Path:
    """An OpenCV cv::omnidir FileStorage file (no distortion)."""
    k = f"[{gamma}, 0., {CX}, 0., {gamma}, {CY}, 0., 0., 1.]"
    path.write_text(
        "%YAML:1.0\n---\n"
        f"K: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: {k}\n"
        f"xi: {xi}\n"
        "D: !!opencv-matrix\n   rows: 1\n   cols: 4\n   dt: d\n   data: [0., 0., 0., 0.]\n"
    )
    return path


def paracatadioptric_pixels(theta: np.ndarray, below_rad: np.ndarray) -> np.ndarray:
    """Where world azimuth theta, below_rad from straight down, lands (closed form above)."""
    radius = G * np.tan(below_rad / 2)
    return np.stack([CX + radius * np.cos(theta), CY + radius * np.sin(theta)], -1)


def test_a_mirror_cameras_calibration_gives_the_world_not_its_mirror_image(tmp_path: Path) -> None:
    path = omnidir_file(tmp_path / "omnidir.yaml", G, 1.0)
    theta, below = np.meshgrid(np.linspace(0, 2 * np.pi, 36, endpoint=False), np.radians(np.linspace(15, 80, 14)))
    theta, below = theta.ravel(), below.ravel()
    truth = paracatadioptric_pixels(theta, below)
    rho = below - math.pi / 2
    mirror = import_calibration(path, image_size=(640, 480), size=(512, 128), mirror=True)
    error = np.hypot(*(mirror.sample(theta, rho).astype(np.float64) - truth).T)
    assert mirror.model.s == 1
    assert error.max() < 0.012  # px: 3x the worst measured, 0.0036 (median 0.0005: float32 entries, bilinear)
    # As a lens (the default), the same file's world is mirrored: north and south swap, a median 58 px off.
    lens = import_calibration(path, image_size=(640, 480), size=(512, 128))
    assert np.percentile(np.hypot(*(lens.sample(theta, rho).astype(np.float64) - truth).T), 50) > 20


def annulus_picture(path: Path, cutoff_px: float, outer_px: float) -> Path:
    """A mirror camera's picture: a textured annulus about (CX, CY), dark inside the cut-off disc and outside."""
    rng = np.random.default_rng(0)
    v, u = np.mgrid[0:480, 0:640]
    radius = np.hypot(u - CX, v - CY)
    image = cv2.GaussianBlur((150 + 60 * rng.random((480, 640))).astype(np.uint8), (0, 0), 1.5)
    image[(radius > outer_px) | (radius < cutoff_px)] = 8
    cv2.imwrite(str(path), image)
    return path


def imported(folder: Path, gamma: float, xi: float, cutoff_px: float, *options: str) -> tuple[Path, Path, Result]:
    """``panomap import`` of an omnidir file (``gamma``, ``xi``) with ``--image`` a picture of a cut-off disc of
    ``cutoff_px`` and a rim of 150 px: the file, the table's path and the command's result."""
    path = omnidir_file(folder / "omnidir.yaml", gamma, xi)
    image = annulus_picture(folder / "omni.png", cutoff_px, 150.0)
    out = folder / "cam.npz"
    return path, out, run("import", path, "-o", out, "--image", image, "--table-size", "256x128", *options)


def test_import_takes_a_picture_with_a_cut_off_disc_for_a_mirror_camera(tmp_path: Path) -> None:
    _, out, result = imported(tmp_path, G, 1.0, 30.0)
    assert result.exit_code == 0, result.stderr
    assert "a mirror camera" in result.stdout
    table = load_table(out)
    assert table.model.s == 1
    # The circles found in the picture (drawn at 30 and 150 px): measured 0.10 and 0.0013 px off.
    assert abs(table.cutoff_radius - 30.0) < 0.3 and abs(table.outer_radius - 150.0) < 0.3
    theta = np.radians(np.arange(0.0, 360.0, 15.0))
    below = np.full_like(theta, math.radians(70.0))
    error = np.hypot(
        *(table.sample(theta, below - math.pi / 2).astype(np.float64) - paracatadioptric_pixels(theta, below)).T
    )
    assert error.max() < 0.015  # px: measured 0.0056
    assert "(a mirror camera: its frame is the world mirrored)" in run("info", out).stdout
    _, _, result = imported(tmp_path, G, 1.0, 30.0, "--lens")
    assert result.exit_code == 0, result.stderr
    assert "a mirror camera" not in result.stdout
    assert load_table(out).model.s == -1


def test_a_found_circle_beyond_the_models_range_stops_the_table_there(tmp_path: Path) -> None:
    # Unified with xi = 1.5: the radius g sin(a) / (xi + cos(a)) grows up to cos(a) = -1/xi, where it is
    # g / sqrt(xi^2 - 1) (107.3 px here); the picture's circle is 150 px: the table stops at 107.3 px, with a note.
    gamma, xi = 120.0, 1.5
    reach = gamma / math.sqrt(xi**2 - 1)
    path, out, result = imported(tmp_path, gamma, xi, 0.0)
    assert result.exit_code == 0, result.stderr
    assert "reaches beyond the mei model's valid range; the table stops there" in result.stderr
    table = load_table(out)
    # Measured 1.3e-4 px and 0.066 deg off: the radius is flat at its top, so its angle is found more loosely.
    assert abs(table.outer_radius - reach) < 1e-3
    assert abs(math.degrees(table.elevation_range[1]) - (math.degrees(math.acos(-1 / xi)) - 90)) < 0.2
    assert table.model.s == -1  # a lens: no cut-off disc
    # A radius typed beyond the model is still refused (the user asked for what the calibration cannot give).
    result = run("import", path, "-o", out, "--image-size", "640x480", "--outer-radius", "150")
    assert result.exit_code == 1 and "reaches beyond the mei model's valid range" in result.stderr


def test_without_a_picture_a_model_of_mirror_cameras_is_taken_as_a_lens_and_said_so(tmp_path: Path) -> None:
    path = omnidir_file(tmp_path / "omnidir.yaml", G, 1.0)
    out = tmp_path / "cam.npz"
    result = run("import", path, "-o", out, "--image-size", "640x480", "--table-size", "256x128")
    assert result.exit_code == 0, result.stderr
    assert "note: taken as a lens; a mirror camera's needs --mirror (or --image)" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and len(result.stderr) < 100
    assert load_table(out).model.s == -1
    quiet = run("import", path, "-o", out, "--image-size", "640x480", "--table-size", "256x128", "-q")
    assert quiet.exit_code == 0 and quiet.stderr == "" and quiet.stdout == ""  # (a note is no warning: -q silences it)
    for choice, s in (("--lens", -1), ("--mirror", 1)):
        result = run("import", path, "-o", out, "--image-size", "640x480", "--table-size", "256x128", choice)
        assert result.exit_code == 0 and "taken as a lens" not in result.stderr, result.stderr
        assert load_table(out).model.s == s


def test_the_lens_note_is_said_only_where_the_calibration_could_be_a_mirror_cameras(tmp_path: Path) -> None:
    """The unified model with xi = 1 sees 2 atan(r / gamma) off its axis at r px (closed form above): with gamma
    120, the frame's 240 px circle sees 127 deg, beyond the horizon as a mirror camera does (said); with gamma
    300, 77 deg, as no mirror camera (not said)."""
    for gamma, said in ((120.0, True), (300.0, False)):
        path = omnidir_file(tmp_path / f"omnidir{gamma:g}.yaml", gamma, 1.0)
        result = run("import", path, "-o", tmp_path / "cam.npz", "--image-size", "640x480", "--table-size", "256x128")
        assert result.exit_code == 0, result.stderr
        assert ("taken as a lens" in result.stderr) is said, result.stderr


FISHEYE = Path(__file__).resolve().parents[1].parent / "shared/data/real/ocam_fisheye_imgback"


@pytest.mark.skipif(not FISHEYE.is_dir(), reason=f"real data not found at {FISHEYE} (../shared is not beside the repo)")
def test_the_shared_ocamcalib_fisheye_imports_without_the_lens_note(tmp_path: Path) -> None:
    """The shared OCamCalib fisheye sees 70 deg off its axis at the frame's edge, 85 deg at its rim: a lens, with
    or without its picture, and no note says it might not be."""
    for image in ((), ("--image", FISHEYE / "images/imgBack1.jpg")):
        result = run("import", FISHEYE / "calib_results.txt", "-o", tmp_path / "cam.npz", *image)
        assert result.exit_code == 0 and result.stderr == "", result.stderr
        assert load_table(tmp_path / "cam.npz").model.s == -1


def test_a_picture_without_a_rim_gets_one_short_note_without_a_centre_to_start_from(tmp_path: Path) -> None:
    """A picture whose frame the scene fills (no rim): the import says so in one line, without centre finding's
    advice on where a centre may start (the calibration gives the centre), and the table spans the model's range
    within the frame."""
    path = omnidir_file(tmp_path / "omnidir.yaml", 300.0, 1.0)
    picture = np.random.default_rng(0).integers(0, 256, (480, 640, 3), dtype=np.uint8)
    cv2.imwrite(str(tmp_path / "full.png"), cv2.GaussianBlur(picture, (0, 0), 2.0))
    result = run("import", path, "-o", tmp_path / "cam.npz", "--image", tmp_path / "full.png", "--table-size",
                 "256x128")  # fmt: skip
    assert result.exit_code == 0, result.stderr
    notes = result.stderr.strip().splitlines()
    assert len(notes) == 1 and notes[0].startswith("panomap: note: full.png: no image circle found"), notes
    assert "only a start" not in notes[0] and len(notes[0]) <= 160, notes[0]
    assert load_table(tmp_path / "cam.npz").cutoff_radius == 0.0
