"""Calibrations in and out (issue 36): each format's equations written here, independently of panomap.

Frames, as docs/calibration-formats.md states them: a calibration's OpenCV frame (x right, y down, z
the optical axis) sits in the level table looking down as world (X, -Y, -Z); OCamCalib's frame
(x the rows, y the columns, rays toward -z) is (y, x, -z) of OpenCV's; COLMAP's pixel centres are
at +0.5. Tolerances: the tables reproduce their calibrations to about 1e-3 px (float32 entries and
bilinear reading), so 0.01 px; a 0.05 px shift of anything fails.
"""

from __future__ import annotations

import csv
import json
import math
import re
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from panomap import export_calibration, import_calibration, load_table, save_table
from panomap.simulate import standard_cameras

from helpers import assert_one_line_error, learn_table, run, spread_landmarks

REAL = Path(__file__).resolve().parents[2] / "shared" / "data" / "real"
needs_real = pytest.mark.skipif(
    not REAL.is_dir(), reason=f"real data not found at {REAL} (../shared is not beside the repo)"
)
OCAM_SETS = ("ocam_fisheye_imgback", "ocam_kaidan_catadioptric", "ocam_miniomni_catadioptric", "ocam_vmr_catadioptric")
TOLERANCE_PX = 0.01


# ----------------------------------------------------------------------------- the equations, written here


def angles_of_world(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Azimuth (from +X, counter-clockwise seen from above) and elevation (rad) of world rays."""
    return np.mod(np.arctan2(d[..., 1], d[..., 0]), 2 * np.pi), np.arctan2(d[..., 2], np.hypot(d[..., 0], d[..., 1]))


def world_of_opencv(ray: np.ndarray) -> np.ndarray:
    """The table's world ray (looking down, level) of a ray in the calibration's OpenCV frame."""
    return ray * np.array([1.0, -1.0, -1.0])


def parse_ocam(path: Path) -> dict[str, object]:
    rows = [line.split() for line in path.read_text().splitlines() if line.strip() and not line.startswith("#")]
    return {
        "pol": [float(x) for x in rows[0][1:]],
        "invpol": [float(x) for x in rows[1][1:]],
        "xc": float(rows[2][0]),
        "yc": float(rows[2][1]),
        "c": float(rows[3][0]),
        "d": float(rows[3][1]),
        "e": float(rows[3][2]),
        "height": int(float(rows[4][0])),
        "width": int(float(rows[4][1])),
    }


def ocam_cam2world(o: dict, row: np.ndarray, col: np.ndarray) -> np.ndarray:
    """OCamCalib's cam2world (ocam_functions.c): rays in OCam's frame."""
    det = o["c"] - o["d"] * o["e"]
    xp = ((row - o["xc"]) - o["d"] * (col - o["yc"])) / det
    yp = (-o["e"] * (row - o["xc"]) + o["c"] * (col - o["yc"])) / det
    r = np.hypot(xp, yp)
    zp = sum(a * r**k for k, a in enumerate(o["pol"]))
    return np.stack([xp, yp, zp], axis=-1)


def ocam_world2cam(o: dict, ray: np.ndarray) -> np.ndarray:
    """OCamCalib's world2cam with its inverse polynomial: (row, col) of rays in OCam's frame."""
    norm = np.hypot(ray[..., 0], ray[..., 1])
    t = np.arctan(ray[..., 2] / norm)
    rho = sum(p * t**k for k, p in enumerate(o["invpol"]))
    x, y = ray[..., 0] / norm * rho, ray[..., 1] / norm * rho
    return np.stack([x * o["c"] + y * o["d"] + o["xc"], x * o["e"] + y + o["yc"]], axis=-1)


def mei_project(ray: np.ndarray, xi, fx, fy, cx, cy, k1=0.0, k2=0.0, p1=0.0, p2=0.0) -> np.ndarray:
    s = ray / np.linalg.norm(ray, axis=-1, keepdims=True)
    x, y = s[..., 0] / (s[..., 2] + xi), s[..., 1] / (s[..., 2] + xi)
    r2 = x * x + y * y
    xd = x * (1 + k1 * r2 + k2 * r2 * r2) + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * (1 + k1 * r2 + k2 * r2 * r2) + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    return np.stack([fx * xd + cx, fy * yd + cy], axis=-1)


def kb_project(ray: np.ndarray, fx, fy, cx, cy, k1, k2, k3, k4) -> np.ndarray:
    r = np.hypot(ray[..., 0], ray[..., 1])
    theta = np.arctan2(r, ray[..., 2])
    theta_d = theta * (1 + k1 * theta**2 + k2 * theta**4 + k3 * theta**6 + k4 * theta**8)
    return np.stack([fx * theta_d * ray[..., 0] / r + cx, fy * theta_d * ray[..., 1] / r + cy], axis=-1)


def eucm_project(ray: np.ndarray, alpha, beta, fx, fy, cx, cy) -> np.ndarray:
    d = np.sqrt(beta * (ray[..., 0] ** 2 + ray[..., 1] ** 2) + ray[..., 2] ** 2)
    m = alpha * d + (1 - alpha) * ray[..., 2]
    return np.stack([fx * ray[..., 0] / m + cx, fy * ray[..., 1] / m + cy], axis=-1)


def fan(max_angle_deg: float, min_angle_deg: float = 1.0, azimuths: int = 90, angles: int = 60) -> np.ndarray:
    """Rays (n, 3) in an OpenCV frame from ``min`` to ``max`` deg off the axis, all around."""
    a = np.radians(np.linspace(min_angle_deg, max_angle_deg, angles))[:, None]
    phi = np.linspace(0, 2 * np.pi, azimuths, endpoint=False)[None, :]
    return np.stack(np.broadcast_arrays(np.sin(a) * np.cos(phi), np.sin(a) * np.sin(phi), np.cos(a)), -1).reshape(-1, 3)


def table_error(table, rays_opencv: np.ndarray, uv: np.ndarray) -> float:
    """Largest distance (px) between the table's pixels of rays (OpenCV frame) and ``uv``."""
    theta, rho = angles_of_world(world_of_opencv(rays_opencv))
    got = table.sample(theta, rho).astype(np.float64)
    assert np.all(np.isfinite(got)), "the table misses rays it should hold"
    return float(np.max(np.hypot(*(got - uv).T)))


# ----------------------------------------------------------------------------- import: real calibrations


@needs_real
@pytest.mark.parametrize("name", OCAM_SETS)
def test_real_ocam_calibrations_are_reproduced_at_every_pixel_of_their_corner_radii(name: str) -> None:
    path = REAL / name / "calib_results.txt"
    o = parse_ocam(path)
    table = import_calibration(path)
    with open(REAL / name / "corners.csv") as f:
        corners = np.array([[float(r["row_px"]), float(r["col_px"])] for r in csv.DictReader(f)])
    radius = np.hypot(corners[:, 0] - o["xc"], corners[:, 1] - o["yc"])
    rows, cols = np.mgrid[0 : o["height"], 0 : o["width"]].astype(np.float64)
    r = np.hypot(rows - o["xc"], cols - o["yc"])
    inside = (r >= radius.min()) & (r <= radius.max())
    row, col = rows[inside], cols[inside]
    ray = ocam_cam2world(o, row, col)
    world = np.stack([ray[:, 1], -ray[:, 0], ray[:, 2]], axis=-1)  # OCam (x, y, z) -> OpenCV (y, x, -z) -> world
    theta, rho = angles_of_world(world)
    got = table.sample(theta, rho).astype(np.float64)
    error = np.hypot(got[:, 0] - col, got[:, 1] - row)
    assert error.max() < TOLERANCE_PX, error.max()  # measured: 1e-3 px at worst (float32)
    # And back: the table's unproject gives the calibration's rays (non-radial affine included).
    theta_back, rho_back = table.unproject(np.stack([col, row], axis=-1))
    back = np.stack(
        [np.cos(rho_back) * np.cos(theta_back), np.cos(rho_back) * np.sin(theta_back), np.sin(rho_back)], -1
    )
    cosine = np.sum(back * world, axis=-1) / np.linalg.norm(world, axis=-1)
    assert np.degrees(np.max(np.arccos(np.clip(cosine, -1, 1)))) < 0.01  # measured: 2e-3 deg


@needs_real
@pytest.mark.parametrize("variant", ["unified_no_distortion", "unified_full_k1k2p1p2"])
def test_real_mei_calibration_as_a_kalibr_omni_camchain(tmp_path: Path, variant: str) -> None:
    calib = json.loads((REAL / "mei_paracatadioptric" / "omnidir_calibration.json").read_text())
    model = calib["models"][variant]
    (fx, _, cx), (_, fy, cy), _ = model["K"]
    xi, distortion = model["xi"], model["D_k1_k2_p1_p2"]
    width, height = calib["image_size_wh"]
    camchain = {
        "cam0": {
            "camera_model": "omni",
            "intrinsics": [xi, fx, fy, cx, cy],
            "distortion_model": "radtan" if any(distortion) else "none",
            "distortion_coeffs": distortion if any(distortion) else [],
            "resolution": [width, height],
        }
    }
    path = tmp_path / "camchain.yaml"
    path.write_text(yaml.safe_dump(camchain))
    table = import_calibration(path)
    with open(REAL / "mei_paracatadioptric" / "corners.csv") as f:
        rows = [r for r in csv.DictReader(f) if r["pose_available"] == "1"]
    ray = np.array([[float(r["cam_X_mm"]), float(r["cam_Y_mm"]), float(r["cam_Z_mm"])] for r in rows])
    # Every direction over the corners' angles from the axis (not only the corners).
    angle = np.degrees(np.arccos(ray[:, 2] / np.linalg.norm(ray, axis=1)))
    rays = fan(angle.max(), angle.min(), azimuths=360, angles=200)
    assert table_error(table, rays, mei_project(rays, xi, fx, fy, cx, cy, *distortion)) < TOLERANCE_PX


def test_kalibr_double_sphere(tmp_path: Path) -> None:
    xi, alpha, fx, fy, cx, cy = -0.21, 0.58, 200.0, 199.0, 640.3, 511.8
    path = tmp_path / "camchain.yaml"
    path.write_text(
        yaml.safe_dump(
            {
                "cam0": {
                    "camera_model": "ds",
                    "intrinsics": [xi, alpha, fx, fy, cx, cy],
                    "distortion_model": "none",
                    "distortion_coeffs": [],
                    "resolution": [1280, 1024],
                }
            }
        )
    )
    table = import_calibration(path)
    rays = fan(95.0)
    d1 = np.linalg.norm(rays, axis=1)
    d2 = np.sqrt(rays[:, 0] ** 2 + rays[:, 1] ** 2 + (xi * d1 + rays[:, 2]) ** 2)
    m = alpha * d2 + (1 - alpha) * (xi * d1 + rays[:, 2])
    expected = np.stack([fx * rays[:, 0] / m + cx, fy * rays[:, 1] / m + cy], -1)
    assert table_error(table, rays, expected) < TOLERANCE_PX


# ----------------------------------------------------------------------------- import: synthetic calibrations

KB_190 = {"fx": 310.0, "fy": 309.2, "cx": 599.3, "cy": 601.7, "k": [0.021, -0.0043, 0.0011, -0.00019]}


def write_kb_camchain(path: Path, kb: dict = KB_190) -> Path:
    camchain = {
        "cam0": {
            "camera_model": "pinhole",
            "intrinsics": [kb["fx"], kb["fy"], kb["cx"], kb["cy"]],
            "distortion_model": "equidistant",
            "distortion_coeffs": kb["k"],
            "resolution": [1200, 1200],
        },
        "cam1": {
            "camera_model": "eucm",
            "intrinsics": [0.6, 1.1, 300.0, 300.0, 600.0, 600.0],
            "distortion_model": "none",
            "distortion_coeffs": [],
            "resolution": [1200, 1200],
        },
    }
    path.write_text(yaml.safe_dump(camchain))
    return path


def test_a_190_degree_kannala_brandt_in_kalibr_form_is_reproduced_past_90_degrees(tmp_path: Path) -> None:
    table = import_calibration(write_kb_camchain(tmp_path / "camchain.yaml"))
    rays = fan(95.0)
    expected = kb_project(rays, KB_190["fx"], KB_190["fy"], KB_190["cx"], KB_190["cy"], *KB_190["k"])
    assert table_error(table, rays, expected) < TOLERANCE_PX
    # The equations above are OpenCV's own where it has them (in front of the camera).
    front = fan(85.0)
    k = np.array([[KB_190["fx"], 0, KB_190["cx"]], [0, KB_190["fy"], KB_190["cy"]], [0, 0, 1.0]])
    opencv, _ = cv2.fisheye.projectPoints(front[None], np.zeros(3), np.zeros(3), k, np.array(KB_190["k"]))
    assert (
        np.max(
            np.abs(opencv[0] - kb_project(front, KB_190["fx"], KB_190["fy"], KB_190["cx"], KB_190["cy"], *KB_190["k"]))
        )
        < 1e-6
    )
    # A shift of 0.05 px of the centre is seen.
    assert table_error(table, rays, expected + np.array([0.05, 0.0])) > 0.04


def test_kalibr_camera_name_picks_the_camera(tmp_path: Path) -> None:
    table = import_calibration(write_kb_camchain(tmp_path / "camchain.yaml"), camera="cam1")
    rays = fan(100.0)
    assert table_error(table, rays, eucm_project(rays, 0.6, 1.1, 300.0, 300.0, 600.0, 600.0)) < TOLERANCE_PX
    assert table.info["import"]["camera"] == "cam1"


@pytest.mark.parametrize("suffix", [".yaml", ".json"])
def test_opencv_fisheye_filestorage_matches_cv2_fisheye(tmp_path: Path, suffix: str) -> None:
    k = np.array([[420.0, 0, 640.2], [0, 421.5, 480.9], [0, 0, 1.0]])
    d = np.array([[0.05, -0.012, 0.003, -0.0004]])
    path = tmp_path / f"fisheye{suffix}"
    storage = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    storage.write("image_width", 1280)
    storage.write("image_height", 960)
    storage.write("camera_matrix", k)  # the spelling of OpenCV's calibration samples
    storage.write("distortion_coefficients", d)
    storage.release()
    table = import_calibration(path)
    rays = fan(80.0)
    expected, _ = cv2.fisheye.projectPoints(rays[None], np.zeros(3), np.zeros(3), k, d)
    inside = (
        (expected[0, :, 0] >= 0) & (expected[0, :, 0] <= 1279) & (expected[0, :, 1] >= 0) & (expected[0, :, 1] <= 959)
    )
    assert table_error(table, rays[inside], expected[0][inside]) < TOLERANCE_PX
    # unproject agrees with cv2.fisheye.undistortPoints (x/z, y/z of the ray).
    uv = expected[0][inside][::7]
    theta, rho = table.unproject(uv)
    world = np.stack([np.cos(rho) * np.cos(theta), np.cos(rho) * np.sin(theta), np.sin(rho)], -1)
    ray = world * [1, -1, -1]
    normalised = cv2.fisheye.undistortPoints(uv[None], k, d)[0]
    assert np.max(np.abs(ray[:, :2] / ray[:, 2:] - normalised)) < 1e-4


@pytest.mark.skipif(not hasattr(cv2, "omnidir"), reason="cv2.omnidir is in opencv-contrib only")
def test_opencv_omnidir_matches_cv2_omnidir(tmp_path: Path) -> None:
    k = np.array([[300.0, 0.5, 640.0], [0, 299.0, 512.0], [0, 0, 1.0]])
    d = np.array([[0.01, -0.002, 0.0005, -0.0003]])
    path = tmp_path / "omni.yaml"
    storage = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    for key, value in (("image_width", 1280), ("image_height", 1024), ("K", k), ("D", d), ("xi", 1.1)):
        storage.write(key, value)
    storage.release()
    table = import_calibration(path)
    rays = fan(100.0)
    expected, _ = cv2.omnidir.projectPoints(rays[None], np.zeros(3), np.zeros(3), k, 1.1, d)
    assert table_error(table, rays, expected[0]) < TOLERANCE_PX


def test_colmap_pixel_centres_and_eucm_order(tmp_path: Path) -> None:
    kb = KB_190
    k = " ".join(str(x) for x in kb["k"])
    path = tmp_path / "cameras.txt"
    path.write_text(
        "# Camera list with one line of data per camera:\n"
        f"1 OPENCV_FISHEYE 1200 1200 {kb['fx']} {kb['fy']} {kb['cx'] + 0.5} {kb['cy'] + 0.5} {k}\n"
        "2 EUCM 1200 1200 300 300 600.5 600.5 0.6 1.1\n"
        "3 THIN_PRISM_FISHEYE 1200 1200 300 301 600.5 600.5 0.01 -0.002 0.001 -0.0005 0.0003 -0.0001 0.002 -0.001\n"
    )
    rays = fan(85.0)
    kb_table = import_calibration(path)  # the first camera: COLMAP's centre is at +0.5
    assert (
        table_error(kb_table, rays, kb_project(rays, kb["fx"], kb["fy"], kb["cx"], kb["cy"], *kb["k"])) < TOLERANCE_PX
    )
    eucm = import_calibration(path, camera="2")  # COLMAP: fx fy cx cy alpha beta
    assert table_error(eucm, rays, eucm_project(rays, 0.6, 1.1, 300.0, 300.0, 600.0, 600.0)) < TOLERANCE_PX
    # THIN_PRISM_FISHEYE (COLMAP's src/colmap/sensor/models.h), written out here.
    fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, sx1, sy1 = (
        300,
        301,
        600.0,
        600.0,
        0.01,
        -0.002,
        0.001,
        -0.0005,
        0.0003,
        -0.0001,
        0.002,
        -0.001,
    )
    a, b = rays[:, 0] / rays[:, 2], rays[:, 1] / rays[:, 2]
    r = np.hypot(a, b)
    a, b = a * np.arctan(r) / r, b * np.arctan(r) / r
    s2 = a * a + b * b
    radial = k1 * s2 + k2 * s2**2 + k3 * s2**3 + k4 * s2**4
    ad = a * (1 + radial) + 2 * p1 * a * b + p2 * (s2 + 2 * a * a) + sx1 * s2
    bd = b * (1 + radial) + 2 * p2 * a * b + p1 * (s2 + 2 * b * b) + sy1 * s2
    prism = import_calibration(path, camera="3")
    assert table_error(prism, rays, np.stack([fx * ad + cx, fy * bd + cy], -1)) < TOLERANCE_PX
    # FOV and RADIAL_FISHEYE (COLMAP's models.h), written out here.
    path.write_text("7 FOV 1200 1200 400 401 600.5 600.5 0.9\n8 RADIAL_FISHEYE 1200 1200 320 600.5 600.5 0.02 -0.003\n")
    rays = fan(70.0)
    a, b = rays[:, 0] / rays[:, 2], rays[:, 1] / rays[:, 2]
    r = np.hypot(a, b)
    factor = np.arctan(2 * r * np.tan(0.9 / 2)) / (0.9 * r)
    fov = import_calibration(path, camera="7")
    assert table_error(fov, rays, np.stack([400 * a * factor + 600, 401 * b * factor + 600], -1)) < TOLERANCE_PX
    theta = np.arctan(r)
    factor = theta * (1 + 0.02 * theta**2 - 0.003 * theta**4) / r
    radial = import_calibration(path, camera="8")
    assert table_error(radial, rays, np.stack([320 * a * factor + 600, 320 * b * factor + 600], -1)) < TOLERANCE_PX


# ----------------------------------------------------------------------------- export


@pytest.fixture(scope="module")
def fitted_table(tmp_path_factory: pytest.TempPathFactory):
    """A table fitted from 40 landmarks of a simulated hyperbolic-mirror camera, saved."""
    camera = standard_cameras((800, 800), centre=(401.3, 396.2), s=-1, phi0=0.4)["hyperbolic"]
    position = (0.3, -0.2, 2.5)
    landmarks = spread_landmarks(camera, position, 40, np.random.default_rng(3))
    table, _ = learn_table(camera, position, landmarks, (800, 800))
    path = tmp_path_factory.mktemp("export") / "cam.npz"
    save_table(table, path)
    return load_table(path), path


def annulus_samples(table) -> tuple[np.ndarray, np.ndarray]:
    """The table's pixels on a grid over its range, and the rays (OpenCV frame of the export) of them."""
    theta, rho = np.meshgrid(
        np.linspace(0, 2 * np.pi, 240, endpoint=False), np.linspace(*table.elevation_range, 82)[1:-1], indexing="ij"
    )
    uv = table.sample(theta, rho).astype(np.float64).reshape(-1, 2)
    # The exported frame: z the optical axis, the ray at image angle phi = s theta + phi0 (the table's own
    # azimuth mapping), alpha from the axis (rho + pi/2 looking down).
    alpha, phi = (rho + np.pi / 2).ravel(), (table.model.s * theta + table.model.phi0).ravel()
    ray = np.stack([np.sin(alpha) * np.cos(phi), np.sin(alpha) * np.sin(phi), np.cos(alpha)], -1)
    good = np.all(np.isfinite(uv), axis=1)
    return uv[good], ray[good]


def printed_error(output: str) -> float:
    return float(re.search(r"over its valid range: ([0-9.]+) px", output).group(1))


def test_export_ocam_reads_back_by_ocamcalibs_world2cam(fitted_table, tmp_path: Path) -> None:
    table, path = fitted_table
    out = tmp_path / "calib_results.txt"
    result = run("export", path, "-o", out, "--format", "ocam")
    assert result.exit_code == 0, result.output + result.stderr
    o = parse_ocam(out)
    uv, ray = annulus_samples(table)
    row_col = ocam_world2cam(o, np.stack([ray[:, 1], ray[:, 0], -ray[:, 2]], -1))
    error = np.hypot(row_col[:, 1] - uv[:, 0], row_col[:, 0] - uv[:, 1])
    assert error.max() < 0.5
    assert error.max() <= printed_error(result.output) + 1e-3


def test_export_kalibr_omni_reads_back_by_meis_equations(fitted_table, tmp_path: Path) -> None:
    table, path = fitted_table
    out = tmp_path / "camchain.yaml"
    result = run("export", path, "-o", out, "--format", "kalibr-omni")
    assert result.exit_code == 0, result.output + result.stderr
    cam = yaml.safe_load(out.read_text())["cam0"]
    assert cam["camera_model"] == "omni" and cam["resolution"] == [800, 800]
    xi, fx, fy, cx, cy = cam["intrinsics"]
    uv, ray = annulus_samples(table)
    error = np.hypot(*(mei_project(ray, xi, fx, fy, cx, cy, *cam["distortion_coeffs"]) - uv).T)
    assert error.max() < 0.5
    assert error.max() <= printed_error(result.output) + 1e-3


def test_export_refuses_a_190_degree_lens_as_opencv_fisheye(tmp_path: Path) -> None:
    table_path = tmp_path / "kb.npz"
    assert run("import", write_kb_camchain(tmp_path / "camchain.yaml"), "-o", table_path).exit_code == 0
    out = tmp_path / "fisheye.yaml"
    result = run("export", table_path, "-o", out, "--format", "opencv-fisheye")
    assert_one_line_error(result, "opencv-fisheye cannot hold this camera", "below 90 deg")
    assert not out.exists()
    # Kalibr's equidistant form holds it (the file's equations, read back here).
    out = tmp_path / "kb.yaml"
    result = run("export", table_path, "-o", out, "--format", "kalibr-equidistant")
    assert result.exit_code == 0, result.stderr
    cam = yaml.safe_load(out.read_text())["cam0"]
    rays = fan(94.0)
    table = load_table(table_path)
    expected = kb_project(rays, *cam["intrinsics"], *cam["distortion_coeffs"])
    assert table_error(table, rays, expected) <= printed_error(result.output) + 1e-3


# ----------------------------------------------------------------------------- the command line and bad files


@needs_real
def test_import_command_and_info(tmp_path: Path) -> None:
    out = tmp_path / "cam.npz"
    result = run("import", REAL / "ocam_fisheye_imgback" / "calib_results.txt", "-o", out)
    assert result.exit_code == 0, result.stderr
    info = run("info", out)
    assert "imported from calib_results.txt (ocam calibration" in info.output


OCAM_GOOD = """#polynomial coefficients for the DIRECT mapping function
5 -2.063866e+02 0.000000e+00 2.165610e-03 -4.495456e-06 1.810639e-08
#polynomial coefficients for the inverse mapping function
3 293.0 151.5 -11.1
#center: "row" and "column", starting from 0 (C convention)
241.0 385.7
#affine parameters "c", "d", "e"
1.0 0.0 0.0
#image size: "height" and "width"
480 748
"""


@pytest.mark.parametrize(
    ("text", "fragments"),
    [
        (OCAM_GOOD.replace("5 -2.06", "6 -2.06"), ("pol (the direct polynomial) declares 6 coefficients and lists 5",)),
        (OCAM_GOOD.replace("480 748\n", ""), ("image size (height width) is missing",)),
        (OCAM_GOOD.replace("1.810639e-08", "-1.810639e-06"), ("turns back at a radius of", "inside the image")),
        (
            "cam0:\n  camera_model: omni\n  distortion_model: none\n  resolution: [640, 480]\n",
            ("cam0.intrinsics is missing",),
        ),
        (
            "cam0:\n  camera_model: pinhole\n  intrinsics: [1, 2, 3, 4]\n  distortion_model: equidistant\n"
            "  distortion_coeffs: [0, 0, 0]\n  resolution: [640, 480]\n",
            ("cam0.distortion_coeffs has 3 values, expected 4",),
        ),
        ("1 OPENCV_FISHEYE 640 480 300 300 320 240 0 0 0\n", ("OPENCV_FISHEYE takes 8 parameters, the line has 7",)),
    ],
)
def test_bad_calibration_files_get_one_line_naming_the_file_and_field(tmp_path: Path, text: str, fragments) -> None:
    path = tmp_path / "calib.txt"
    path.write_text(text)
    out = tmp_path / "cam.npz"
    result = run("import", path, "-o", out)
    assert_one_line_error(result, str(path), *fragments)
    assert not out.exists()


def test_an_image_of_another_size_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "calib_results.txt"
    path.write_text(OCAM_GOOD)
    image = tmp_path / "omni.png"
    cv2.imwrite(str(image), np.zeros((400, 600, 3), np.uint8))
    out = tmp_path / "cam.npz"
    result = run("import", path, "-o", out, "--image", image)
    assert_one_line_error(result, str(path), "748 x 480 images, the image is 600 x 400")
    assert not out.exists()


def test_a_tilted_mount_turns_world_rays_into_the_calibration(tmp_path: Path) -> None:
    tilt, toward = math.radians(8.0), math.radians(30.0)
    table = import_calibration(write_kb_camchain(tmp_path / "camchain.yaml"), tilt_rad=(tilt, toward))
    # R (camera to world), looking down: a turn by the tilt about (sin a, -cos a, 0) (Rodrigues).
    k = np.array([math.sin(toward), -math.cos(toward), 0.0])
    cross = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    rotation = np.eye(3) + math.sin(tilt) * cross + (1 - math.cos(tilt)) * cross @ cross
    theta, rho = np.meshgrid(np.linspace(0, 2 * np.pi, 72, endpoint=False), np.radians(np.linspace(-85, -10, 40)))
    world = np.stack([np.cos(rho) * np.cos(theta), np.cos(rho) * np.sin(theta), np.sin(rho)], -1).reshape(-1, 3)
    level = world @ rotation  # R^T d, row by row
    kb = KB_190
    expected = kb_project(world_of_opencv(level), kb["fx"], kb["fy"], kb["cx"], kb["cy"], *kb["k"])
    got = table.sample(theta.ravel(), rho.ravel()).astype(np.float64)
    assert np.max(np.hypot(*(got - expected).T)) < TOLERANCE_PX
    # and back: unproject gives the world rays (measured 3e-7 rad)
    theta_back, rho_back = table.unproject(expected)
    assert np.max(np.abs(rho_back - rho.ravel())) < 1e-5
    assert np.max(np.abs(np.angle(np.exp(1j * (theta_back - theta.ravel()))))) < 1e-4


def test_round_trip_through_cv2_fisheye_remap(tmp_path: Path) -> None:
    """docs/calibration-formats.md's example: import an OpenCV fisheye, export it back, and compare the
    table's map of the undistorted view with cv2.fisheye.initUndistortRectifyMap's."""
    k = np.array([[300.0, 0, 320.4], [0, 301.5, 240.7], [0, 0, 1.0]])
    d = np.array([[0.04, -0.01, 0.002, -0.0003]])
    source = tmp_path / "fisheye.yaml"
    storage = cv2.FileStorage(str(source), cv2.FILE_STORAGE_WRITE)
    for key, value in (
        ("image_width", 640),
        ("image_height", 480),
        ("camera_matrix", k),
        ("distortion_coefficients", d),
    ):
        storage.write(key, value)
    storage.release()
    table = import_calibration(source)
    exported = export_calibration(table, tmp_path / "again.yaml", "opencv-fisheye")
    back = cv2.FileStorage(str(tmp_path / "again.yaml"), cv2.FILE_STORAGE_READ)
    k2, d2 = back.getNode("K").mat(), back.getNode("D").mat()
    assert np.max(np.abs(k2 - k)) < 1e-3 and np.max(np.abs(d2 - d)) < 1e-5  # measured 4e-5, 2e-7
    map_x, map_y = cv2.fisheye.initUndistortRectifyMap(k2, d2, np.eye(3), k2, (640, 480), cv2.CV_32FC1)
    row, col = np.mgrid[0:480, 0:640].astype(np.float64)
    ray = np.stack([(col - k2[0, 2]) / k2[0, 0], (row - k2[1, 2]) / k2[1, 1], np.ones_like(col)], -1)
    theta, rho = angles_of_world(world_of_opencv(ray))
    uv = table.sample(theta, rho)
    both = np.isfinite(uv[..., 0]) & (map_x >= 0) & (map_x <= 639) & (map_y >= 0) & (map_y <= 479)
    assert both.mean() > 0.95
    difference = np.hypot(uv[..., 0] - map_x, uv[..., 1] - map_y)[both]
    assert difference.max() < max(2 * exported.max_error_px, TOLERANCE_PX)  # measured 3e-4 px


def test_opencv_plain_pinhole_matches_cv2_project_points(tmp_path: Path) -> None:
    k = np.array([[500.0, 0, 320.2], [0, 498.0, 240.6], [0, 0, 1.0]])
    d = np.array([[-0.2, 0.05, 0.001, -0.0008]])
    path = tmp_path / "pinhole.json"
    storage = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    for key, value in (("image_width", 640), ("image_height", 480), ("fisheye_model", 0), ("K", k), ("D", d)):
        storage.write(key, value)
    storage.release()
    table = import_calibration(path)
    rays = fan(24.0)  # inside the 640 x 480 frame
    expected, _ = cv2.projectPoints(rays, np.zeros(3), np.zeros(3), k, d)
    assert table_error(table, rays, expected[:, 0]) < TOLERANCE_PX


def test_colmap_camera_id_on_the_command_line_and_numeric_models(tmp_path: Path) -> None:
    path = tmp_path / "cameras.txt"
    path.write_text("1 PINHOLE 640 480 500 500 320.5 240.5\n2 EUCM 1200 1200 300 300 600.5 600.5 0.6 1.1\n")
    out = tmp_path / "cam.npz"
    result = run("import", path, "-o", out, "--camera-id", "2")
    assert result.exit_code == 0, result.stderr
    assert "colmap calibration, model colmap-eucm (camera 2)" in result.output
    assert load_table(out).info["import"]["pixel_shift_px"] == -0.5
    path.write_text("1 5 640 480 300 300 320 240 0 0 0 0\n")
    result = run("import", path, "-o", tmp_path / "other.npz", "--format", "colmap")
    assert_one_line_error(result, str(path), "numeric id")
