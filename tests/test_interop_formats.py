"""Issue 53: BoofCV, Basalt and gyroflow calibrations in, each against its tool's own equations written here.

The equations below are written out from the tools' sources (BoofCV's ``UniOmniStoP_F64`` and
``KannalaBrandtStoP_F64``/``KannalaBrandtUtils_F64``; basalt-headers' ``double_sphere_camera.hpp``,
``extended_camera.hpp``, ``unified_camera.hpp``, ``kannala_brandt_camera4.hpp`` and
``pinhole_radtan8_camera.hpp``; gyroflow's ``opencv_fisheye.rs`` and ``lens_profile.rs``), not from panomap's
models; gyroflow's is checked against ``cv2.fisheye.projectPoints`` too. Frames as docs/calibration-formats.md
states them: a calibration's OpenCV frame (x right, y down, z the optical axis) sits in the level table
looking down as world (X, -Y, -Z). Tolerance: 0.05 px over each lens's field (the tables reproduce their
calibrations to about 1e-3 px: float32 entries and bilinear reading).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from panomap import import_calibration, load_table
from panomap.interop.readers import READERS, read_calibration

from helpers import assert_one_line_error, run

SCENES = Path(__file__).resolve().parents[2] / "shared" / "data" / "scenes"
needs_scenes = pytest.mark.skipif(
    not SCENES.is_dir(), reason=f"shared scenes not found at {SCENES} (../shared is not beside the repo)"
)
TOLERANCE_PX = 0.05


# ----------------------------------------------------------------------------- the equations, written here


def fan(max_angle_deg: float, min_angle_deg: float = 0.5, azimuths: int = 72, angles: int = 60) -> np.ndarray:
    """Unit rays (n, 3) in an OpenCV frame from ``min`` to ``max`` deg off the axis, all around."""
    a = np.radians(np.linspace(min_angle_deg, max_angle_deg, angles))[:, None]
    phi = np.linspace(0, 2 * np.pi, azimuths, endpoint=False)[None, :] + 0.01
    return np.stack(np.broadcast_arrays(np.sin(a) * np.cos(phi), np.sin(a) * np.sin(phi), np.cos(a)), -1).reshape(-1, 3)


def table_error(table, rays: np.ndarray, uv: np.ndarray, field_deg: float) -> float:
    """Largest distance (px) between the table's pixels of rays (OpenCV frame) and ``uv``, over the rays whose
    ``uv`` lies in the image (a pixel inside its border: the table's bilinear reading needs both
    neighbours); those rays must reach within 2 deg of ``field_deg`` from the axis, so the check runs to
    the lens's edge."""
    width, height = table.image_size
    inside = (uv[:, 0] >= 1) & (uv[:, 0] <= width - 2) & (uv[:, 1] >= 1) & (uv[:, 1] <= height - 2)
    assert np.degrees(np.arccos(rays[inside, 2].min())) > field_deg - 2
    world = rays[inside] * np.array([1.0, -1.0, -1.0])
    theta = np.mod(np.arctan2(world[:, 1], world[:, 0]), 2 * np.pi)
    rho = np.arctan2(world[:, 2], np.hypot(world[:, 0], world[:, 1]))
    got = table.sample(theta, rho).astype(np.float64)
    assert np.all(np.isfinite(got)), "the table misses rays it should hold"
    return float(np.max(np.hypot(*(got - uv[inside]).T)))


def boofcv_universal_omni(ray, fx, fy, cx, cy, skew, xi, radial, t1, t2) -> np.ndarray:
    """BoofCV's UniOmniStoP_F64: a point on the unit sphere, z + mirror offset, radial (any count), tangential."""
    s = ray / np.linalg.norm(ray, axis=-1, keepdims=True)
    x, y = s[:, 0] / (s[:, 2] + xi), s[:, 1] / (s[:, 2] + xi)
    r2 = x * x + y * y
    total = sum(k * r2 ** (i + 1) for i, k in enumerate(radial))
    dx = x * (1 + total) + 2 * t1 * x * y + t2 * (r2 + 2 * x * x)
    dy = y * (1 + total) + t1 * (r2 + 2 * y * y) + 2 * t2 * x * y
    return np.stack([fx * dx + skew * dy + cx, fy * dy + cy], -1)


def boofcv_kannala_brandt(ray, fx, fy, cx, cy, skew, symmetric, radial=(), radial_trig=(), tangent=(), tangent_trig=()):
    """BoofCV's KannalaBrandtStoP_F64 with KannalaBrandtUtils_F64's polynomial and polytrig."""
    theta = np.arccos(ray[:, 2] / np.linalg.norm(ray, axis=-1))
    phi = np.arctan2(ray[:, 1], ray[:, 0])
    c, s = np.cos(phi), np.sin(phi)

    def polynomial(coefs):
        return sum(k * theta ** (2 * i + 1) for i, k in enumerate(coefs)) + 0 * theta

    def polytrig(coefs):
        if not coefs:
            return 0 * theta
        return coefs[0] * c + coefs[1] * s + coefs[2] * 2 * c * s + coefs[3] * (2 * c * c - 1)

    r = polynomial(symmetric)
    dis_rad = polynomial(radial) * polytrig(radial_trig)
    dis_tan = polynomial(tangent) * polytrig(tangent_trig)
    dx = (r + dis_rad) * c - dis_tan * s
    dy = (r + dis_rad) * s + dis_tan * c
    return np.stack([fx * dx + skew * dy + cx, fy * dy + cy], -1)


def basalt_ds(ray, fx, fy, cx, cy, xi, alpha) -> np.ndarray:
    x, y, z = ray.T
    d1 = np.sqrt(x * x + y * y + z * z)
    k = xi * d1 + z
    d2 = np.sqrt(x * x + y * y + k * k)
    norm = alpha * d2 + (1 - alpha) * k
    return np.stack([fx * x / norm + cx, fy * y / norm + cy], -1)


def basalt_eucm(ray, fx, fy, cx, cy, alpha, beta=1.0) -> np.ndarray:
    """Basalt's ExtendedUnifiedCamera (and UnifiedCamera: beta = 1)."""
    x, y, z = ray.T
    rho = np.sqrt(beta * (x * x + y * y) + z * z)
    norm = alpha * rho + (1 - alpha) * z
    return np.stack([fx * x / norm + cx, fy * y / norm + cy], -1)


def basalt_kb4(ray, fx, fy, cx, cy, k1, k2, k3, k4) -> np.ndarray:
    x, y, z = ray.T
    r = np.sqrt(x * x + y * y)
    theta = np.arctan2(r, z)
    r_theta = theta * (1 + k1 * theta**2 + k2 * theta**4 + k3 * theta**6 + k4 * theta**8)
    return np.stack([fx * x * r_theta / r + cx, fy * y * r_theta / r + cy], -1)


def basalt_radtan8(ray, fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, k5, k6) -> np.ndarray:
    xp, yp = ray[:, 0] / ray[:, 2], ray[:, 1] / ray[:, 2]
    rp2 = xp * xp + yp * yp
    cdist = (1 + rp2 * (k1 + rp2 * (k2 + rp2 * k3))) / (1 + rp2 * (k4 + rp2 * (k5 + rp2 * k6)))
    xpp = xp * cdist + 2 * p1 * xp * yp + p2 * (rp2 + 2 * xp * xp)
    ypp = yp * cdist + 2 * p2 * xp * yp + p1 * (rp2 + 2 * yp * yp)
    return np.stack([fx * xpp + cx, fy * ypp + cy], -1)


def gyroflow_fisheye(ray, fx, fy, cx, cy, k) -> np.ndarray:
    """gyroflow's OpenCVFisheye.distort_point, then the camera matrix."""
    x, y = ray[:, 0] / ray[:, 2], ray[:, 1] / ray[:, 2]
    r = np.hypot(x, y)
    theta = np.arctan(r)
    theta_d = theta * (1 + k[0] * theta**2 + k[1] * theta**4 + k[2] * theta**6 + k[3] * theta**8)
    return np.stack([fx * x * theta_d / r + cx, fy * y * theta_d / r + cy], -1)


# ----------------------------------------------------------------------------- the files, written here

OMNI = {
    "fx": 300.0,
    "fy": 301.5,
    "cx": 400.3,
    "cy": 399.6,
    "skew": 0.6,
    "xi": 1.1,
    "radial": [-0.2, 0.01, 0.001],
    "t1": 1e-3,
    "t2": -5e-4,
}
KB_SYMMETRIC = [1.01, 0.02, -0.008, 0.0006, -0.00002]
KB_ASYMMETRIC = {
    "radial": [0.01, -0.002, 0.0003],
    "radial_trig": [0.2, -0.3, 0.25, 0.1],
    "tangent": [0.008, 0.001, -0.0004],
    "tangent_trig": [-0.1, 0.3, 0.2, -0.15],
}


def boofcv_omni_text(**change) -> str:
    o = OMNI | change
    data = {
        "pinhole": {k: o[k] for k in ("fx", "fy", "cx", "cy", "skew")} | {"width": 800, "height": 800},
        "model": "omnidirectional_universal",
        "version": 0,
        "radial_tangential": {"radial": o["radial"], "t1": o["t1"], "t2": o["t2"]},
        "mirror_offset": o["xi"],
    }
    return "# Omnidirectional camera model with radial and tangential distortion\n" + yaml.safe_dump(data)


def boofcv_kb_text(asymmetric: bool, skew: float = 0.0) -> str:
    data = {
        "model": "kannala_brandt",
        "version": 0,
        "pinhole": {"width": 1100, "height": 1000, "fx": 280.0, "fy": 279.0, "skew": skew, "cx": 500.2, "cy": 449.7},
        "symmetric": KB_SYMMETRIC,
    }
    data |= KB_ASYMMETRIC if asymmetric else {"radial": [], "radial_trig": [], "tangent": [], "tangent_trig": []}
    return yaml.safe_dump(data)


BASALT_CAMERAS = {
    "ds": {"fx": 250.1, "fy": 249.7, "cx": 512.4, "cy": 383.2, "xi": -0.18, "alpha": 0.59},
    "eucm": {"fx": 260.0, "fy": 259.0, "cx": 511.0, "cy": 385.5, "alpha": 0.63, "beta": 1.08},
    "ucm": {"fx": 200.0, "fy": 199.0, "cx": 510.0, "cy": 384.0, "alpha": 0.64},
    "kb4": {"fx": 280.5, "fy": 280.1, "cx": 509.9, "cy": 381.1, "k1": 0.02, "k2": -0.006, "k3": 0.0007, "k4": -0.0001},
    "pinhole-radtan8": {
        "fx": 400.0,
        "fy": 401.0,
        "cx": 512.5,
        "cy": 384.5,
        "k1": -0.1,
        "k2": 0.02,
        "p1": 1e-3,
        "p2": -1e-3,
        "k3": 0.001,
        "k4": 0.05,
        "k5": 0.01,
        "k6": 0.001,
    },
}
BASALT_EQUATIONS = {"ds": basalt_ds, "eucm": basalt_eucm, "ucm": basalt_eucm, "kb4": basalt_kb4}
BASALT_EQUATIONS["pinhole-radtan8"] = basalt_radtan8
# The field each camera is checked over (deg from the axis): inside each model's range for these parameters.
BASALT_FIELD_DEG = {"ds": 100.0, "eucm": 100.0, "ucm": 100.0, "kb4": 100.0, "pinhole-radtan8": 60.0}


def basalt_text(types: list[str], poses: bool = True) -> str:
    pose = {"px": 0.1, "py": -0.02, "pz": 0.003, "qx": 0.0, "qy": 0.0, "qz": 0.0, "qw": 1.0}
    value = {
        "T_imu_cam": [pose | {"px": 0.1 * i} for i in range(len(types))],
        "intrinsics": [{"camera_type": t, "intrinsics": BASALT_CAMERAS[t]} for t in types],
        "resolution": [[1024, 768] for _ in types],
        "calib_accel_bias": [0.0] * 9,
        "imu_update_rate": 200.0,
        "cam_time_offset_ns": 0,
        "vignette": [],
    }
    if not poses:
        del value["T_imu_cam"]
    return json.dumps({"value0": value}, indent=4)


GYRO = {"fx": 912.3, "fy": 912.6, "cx": 936.1, "cy": 545.9, "k": [0.0071, -0.0102, 0.0042, -0.0011]}


def gyroflow_profile(**change) -> dict:
    return {
        "name": "Brand_Model_Lens_1080p_16by9_1920x1080-60.00fps",
        "note": "",
        "calibrated_by": "someone",
        "camera_brand": "Brand",
        "camera_model": "Model",
        "lens_model": "Lens",
        "camera_setting": "",
        "calib_dimension": {"w": 1920, "h": 1080},
        "orig_dimension": {"w": 1920, "h": 1080},
        "input_horizontal_stretch": 1.0,
        "input_vertical_stretch": 1.0,
        "num_images": 15,
        "fps": 60.0,
        "asymmetrical": False,
        "fisheye_params": {
            "RMS_error": 0.57,
            "camera_matrix": [[GYRO["fx"], 0.0, GYRO["cx"]], [0.0, GYRO["fy"], GYRO["cy"]], [0.0, 0.0, 1.0]],
            "distortion_coeffs": GYRO["k"],
            "radial_distortion_limit": None,
        },
        "calibrator_version": "1.5.4",
        "date": "2024-01-01",
        "distortion_model": None,
        "digital_lens": None,
    } | change


def write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


# ----------------------------------------------------------------------------- BoofCV


def test_boofcv_universal_omni_with_three_radial_terms_skew_and_tangential(tmp_path: Path) -> None:
    path = write(tmp_path, "omni.yaml", boofcv_omni_text())
    table = import_calibration(path)
    assert table.info["import"]["format"] == "boofcv"
    rays = fan(100.0)
    expected = boofcv_universal_omni(
        rays, *(OMNI[k] for k in ("fx", "fy", "cx", "cy", "skew", "xi", "radial")), OMNI["t1"], OMNI["t2"]
    )
    assert table_error(table, rays, expected, 100.0) < TOLERANCE_PX  # measured: <= 1.3e-3 px


@pytest.mark.parametrize("asymmetric", [False, True], ids=["symmetric", "asymmetric"])
def test_boofcv_kannala_brandt_symmetric_and_asymmetric(tmp_path: Path, asymmetric: bool) -> None:
    skew = 0.4 if asymmetric else 0.0
    path = write(tmp_path, "kb.yaml", boofcv_kb_text(asymmetric, skew))
    table = import_calibration(path)
    assert table.info["import"]["model"] == "kannala-brandt-full"
    rays = fan(100.0)
    terms = KB_ASYMMETRIC if asymmetric else {}
    expected = boofcv_kannala_brandt(rays, 280.0, 279.0, 500.2, 449.7, skew, KB_SYMMETRIC, **terms)
    if asymmetric:  # the terms move pixels by whole pixels: the check sees them
        plain = boofcv_kannala_brandt(rays, 280.0, 279.0, 500.2, 449.7, skew, KB_SYMMETRIC)
        assert np.max(np.hypot(*(expected - plain).T)) > 2.0
    assert table_error(table, rays, expected, 100.0) < TOLERANCE_PX  # measured: <= 1.3e-3 px


@needs_scenes
def test_real_boofcv_theta_back(tmp_path: Path) -> None:
    path = SCENES / "theta_back" / "back.yaml"
    data = yaml.safe_load(path.read_text())
    p, d = data["pinhole"], data["radial_tangential"]
    table = import_calibration(path)
    assert table.image_size == (960, 1080)

    def project(rays: np.ndarray) -> np.ndarray:
        return boofcv_universal_omni(
            rays, p["fx"], p["fy"], p["cx"], p["cy"], p["skew"], data["mirror_offset"], d["radial"], d["t1"], d["t2"]
        )

    # SOURCE.md: the radius at 90 deg off the axis is about 428 px.
    side = project(np.array([[1.0, 0.0, 0.0]]))[0]
    assert abs(math.hypot(side[0] - p["cx"], side[1] - p["cy"]) - 428) < 1
    rays = fan(100.0)  # the lens's field: about 200 deg
    assert table_error(table, rays, project(rays), 100.0) < TOLERANCE_PX  # measured: <= 1.3e-3 px


# ----------------------------------------------------------------------------- Basalt


@pytest.mark.parametrize("kind", list(BASALT_CAMERAS))
def test_basalt_cameras_match_basalts_equations(tmp_path: Path, kind: str) -> None:
    path = write(tmp_path, "calibration.json", basalt_text([kind]))
    table = import_calibration(path)
    assert table.info["import"]["format"] == "basalt" and table.image_size == (1024, 768)
    rays = fan(BASALT_FIELD_DEG[kind])
    expected = BASALT_EQUATIONS[kind](rays, *BASALT_CAMERAS[kind].values())
    assert table_error(table, rays, expected, BASALT_FIELD_DEG[kind]) < TOLERANCE_PX  # measured: <= 1.3e-3 px


@pytest.mark.parametrize("choice", [None, "cam1", "1", "cam2"])
def test_basalt_camera_name_or_index_picks_the_camera_and_poses_are_kept(tmp_path: Path, choice: str | None) -> None:
    types = ["ds", "kb4", "eucm"]
    path = write(tmp_path, "calibration.json", basalt_text(types))
    imported = read_calibration(path, camera=choice)
    index = 0 if choice is None else int(choice[-1])
    assert imported.camera == f"cam{index}"
    rays = fan(90.0)
    expected = BASALT_EQUATIONS[types[index]](rays, *BASALT_CAMERAS[types[index]].values())
    assert np.max(np.hypot(*(imported.model.project(rays) - expected).T)) < 1e-9
    assert [pose.camera for pose in imported.rig_poses] == ["cam0", "cam1", "cam2"]
    assert imported.rig_poses[2].translation_m == (pytest.approx(0.2), -0.02, 0.003)
    assert imported.rig_poses[2].quaternion_xyzw == (0.0, 0.0, 0.0, 1.0)
    assert read_calibration(write(tmp_path, "no_poses.json", basalt_text(types, poses=False))).rig_poses == ()


def test_basalt_camera_name_on_the_command_line(tmp_path: Path) -> None:
    path = write(tmp_path, "calibration.json", basalt_text(["ds", "kb4"]))
    out = tmp_path / "t.npz"
    result = run("import", path, "-o", out, "--camera-name", "cam1", "--table-size", "512x128")
    assert result.exit_code == 0, result.output + result.stderr
    record = load_table(out).info["import"]
    assert (record["format"], record["camera"], record["model"]) == ("basalt", "cam1", "kannala-brandt")
    result = run("import", path, "-o", tmp_path / "u.npz", "--camera-name", "cam7")
    assert_one_line_error(result, str(path), "no camera 'cam7'", "cam0, cam1")


@needs_scenes
def test_real_basalt_ds_building(tmp_path: Path) -> None:
    path = SCENES / "ds_building" / "calibration.json"
    c = json.loads(path.read_text())["value0"]["intrinsics"][0]["intrinsics"]
    table = import_calibration(path)
    assert table.image_size == (640, 480)

    def project(rays: np.ndarray) -> np.ndarray:
        return basalt_ds(rays, c["fx"], c["fy"], c["cx"], c["cy"], c["xi"], c["alpha"])

    # SOURCE.md: the radius at 90 deg is 221.5 px (along x), at 100 deg 251.7 px.
    for angle, radius in ((90, 221.5), (100, 251.7)):
        a = math.radians(angle)
        uv = project(np.array([[math.sin(a), 0.0, math.cos(a)]]))[0]
        assert abs(uv[0] - c["cx"] - radius) < 0.1
    rays = fan(100.0)
    assert table_error(table, rays, project(rays), 100.0) < TOLERANCE_PX  # measured: <= 1.3e-3 px


# ----------------------------------------------------------------------------- gyroflow


@pytest.mark.parametrize("asymmetrical", [False, True])
def test_gyroflow_profile_as_gyroflow_reads_it(tmp_path: Path, asymmetrical: bool) -> None:
    path = write(tmp_path, "profile.json", json.dumps(gyroflow_profile(asymmetrical=asymmetrical), indent=2))
    table = import_calibration(path)
    assert table.info["import"]["format"] == "gyroflow" and table.image_size == (1920, 1080)
    # gyroflow's get_camera_matrix: a profile that is not asymmetrical has its centre at (w/2, h/2).
    cx, cy = (GYRO["cx"], GYRO["cy"]) if asymmetrical else (960.0, 540.0)
    rays = fan(85.0)
    expected = gyroflow_fisheye(rays, GYRO["fx"], GYRO["fy"], cx, cy, GYRO["k"])
    k = np.array([[GYRO["fx"], 0, cx], [0, GYRO["fy"], cy], [0, 0, 1]])
    opencv, _ = cv2.fisheye.projectPoints(rays[None], np.zeros(3), np.zeros(3), k, np.array(GYRO["k"]))
    assert np.max(np.hypot(*(opencv[0] - expected).T)) < 1e-6
    # The 1920 x 1080 frame sees to about 68 deg from the axis (its corners); the model reaches 90 deg.
    assert table_error(table, rays, expected, 66.0) < TOLERANCE_PX  # measured: <= 1.3e-3 px
    notes = table.info["import"]["notes"]
    assert notes[0] == "lens profile 'Brand_Model_Lens_1080p_16by9_1920x1080-60.00fps'"
    assert any("principal point is the image centre (960, 540)" in n for n in notes) != asymmetrical


def test_gyroflow_note_on_the_command_line(tmp_path: Path) -> None:
    path = write(tmp_path, "profile.json", json.dumps(gyroflow_profile(), indent=2))
    result = run("import", path, "-o", tmp_path / "t.npz", "--table-size", "512x128")
    assert result.exit_code == 0, result.output + result.stderr
    assert "not the matrix's (936.10, 545.90)" in result.stderr
    assert "gyroflow calibration, model opencv-fisheye" in result.output


# ----------------------------------------------------------------------------- detection


KALIBR = yaml.safe_dump(
    {
        "cam0": {
            "camera_model": "ds",
            "intrinsics": [-0.2, 0.58, 200.0, 199.0, 640.3, 511.8],
            "distortion_model": "none",
            "distortion_coeffs": [],
            "resolution": [1280, 1024],
        }
    }
)
OPENCV_JSON = json.dumps({"camera_matrix": [300.0, 0, 400, 0, 300.0, 300, 0, 0, 1], "D": [0.01, 0, 0, 0]}, indent=2)


COLMAP = "# Camera list\n1 OPENCV_FISHEYE 1280 1024 300.0 300.0 640.0 512.0 0.01 0.0 0.0 0.0\n"
DETECTED = {
    "boofcv-omni": (boofcv_omni_text(), "boofcv"),
    "boofcv-kb": (boofcv_kb_text(True), "boofcv"),
    "basalt": (basalt_text(["ds"]), "basalt"),
    "gyroflow-indented": (json.dumps(gyroflow_profile(), indent=2), "gyroflow"),
    "gyroflow-one-line": (json.dumps(gyroflow_profile()), "gyroflow"),
    "kalibr": (KALIBR, "kalibr"),
    "opencv-json": (OPENCV_JSON, "opencv"),
    "colmap": (COLMAP, "colmap"),
}


@pytest.mark.parametrize("case", list(DETECTED))
def test_each_format_is_detected_as_itself(tmp_path: Path, case: str) -> None:
    text, expected = DETECTED[case]
    assert read_calibration(write(tmp_path, "calibration", text)).format.startswith(expected)  # opencv-fisheye
    # The new formats claim no other format's file, and no other format claims theirs ahead of them: a
    # gyroflow profile's nested "camera_matrix": and "camera_model": keys meet OpenCV's JSON and Kalibr's
    # detection too, so gyroflow is tried before both (the registry's order).
    claimed = [name for name, entry in READERS.items() if entry.looks_like(text)]
    assert claimed[0] == expected
    new = {"boofcv", "basalt", "gyroflow"}
    assert set(claimed) & new == ({expected} & new)


@needs_scenes
@pytest.mark.parametrize(
    ("name", "expected"), [("theta_back/back.yaml", "boofcv"), ("ds_building/calibration.json", "basalt")]
)
def test_real_files_are_detected(name: str, expected: str) -> None:
    assert read_calibration(SCENES / name).format == expected


@pytest.mark.parametrize("name", ["boofcv", "basalt", "gyroflow"])
def test_format_can_be_forced_and_is_listed(tmp_path: Path, name: str) -> None:
    texts = {
        "boofcv": boofcv_omni_text(),
        "basalt": basalt_text(["kb4"]),
        "gyroflow": json.dumps(gyroflow_profile()),
    }
    path = write(tmp_path, "calibration.txt", texts[name])
    result = run("import", path, "-o", tmp_path / "t.npz", "--format", name, "--table-size", "512x128")
    assert result.exit_code == 0, result.output + result.stderr
    unknown = write(tmp_path, "unknown.json", '{"value": 1}')
    result = run("import", unknown, "-o", tmp_path / "u.npz")
    assert_one_line_error(result, str(unknown), "not a calibration this reads", name)


# ----------------------------------------------------------------------------- bad files


def _omni_without(key: str) -> str:
    data = yaml.safe_load(boofcv_omni_text())
    del data["pinhole"][key]
    return yaml.safe_dump(data)


def _basalt_with(**change) -> str:
    data = json.loads(basalt_text(["ds"]))
    camera = data["value0"]["intrinsics"][0]
    for key, value in change.items():
        if key == "camera_type":
            camera["camera_type"] = value
        elif key == "resolution":
            data["value0"]["resolution"] = value
        elif value is None:
            del camera["intrinsics"][key]
        else:
            camera["intrinsics"][key] = value
    return json.dumps(data)


BAD_FILES = {
    "boofcv-missing-key": ("a.yaml", _omni_without("fx"), ("pinhole.fx is missing",)),
    "boofcv-model": (
        "b.yaml",
        boofcv_omni_text().replace("omnidirectional_universal", "pinhole_radial_tangential"),
        ("BoofCV model 'pinhole_radial_tangential' is not read",),
    ),
    "boofcv-type": ("c.yaml", boofcv_omni_text(xi="abc"), ("mirror_offset is 'abc', not a number",)),
    "boofcv-radial-type": ("d.yaml", boofcv_omni_text(radial="abc"), ("radial_tangential.radial is 'abc'",)),
    "boofcv-trig": (
        "e.yaml",
        boofcv_kb_text(True).replace("radial_trig:\n- 0.2\n", "radial_trig:\n"),
        ("radial_trig has 3 values, expected 4",),
    ),
    "boofcv-xi": ("f.yaml", boofcv_omni_text(xi=-0.5), ("xi must be >= 0",)),
    "basalt-model": ("g.json", _basalt_with(camera_type="fov"), ("camera_type 'fov' is not read", "ds, eucm")),
    "basalt-missing-key": ("h.json", _basalt_with(xi=None), ("value0.intrinsics[0].intrinsics.xi is missing",)),
    "basalt-type": ("i.json", _basalt_with(fx="250"), ("intrinsics.fx is '250', not a number",)),
    "basalt-range": ("j.json", _basalt_with(alpha=1.5), ("alpha must be in [0, 1)",)),
    "basalt-resolution": ("k.json", _basalt_with(resolution=[]), ("value0.resolution has 0 entries for 1 cameras",)),
    "basalt-json": ("l.json", basalt_text(["ds"])[:-5], ("not valid JSON",)),
    "basalt-deep": ("m.json", '{"value0": {"intrinsics": [{"camera_type": ' + "[" * 100_000, ("nested more than",)),
    "gyroflow-model": (
        "n.json",
        json.dumps(gyroflow_profile(distortion_model="poly3")),
        ("distortion_model 'poly3' is not read",),
    ),
    "gyroflow-missing": (
        "o.json",
        json.dumps(gyroflow_profile(fisheye_params={"distortion_coeffs": [0.1] * 4})),
        ("fisheye_params.camera_matrix is missing",),
    ),
    "gyroflow-dimension": (
        "p.json",
        json.dumps(gyroflow_profile(calib_dimension={"w": 1920})),
        ("calib_dimension.h is missing",),
    ),
    "gyroflow-coefficients": (
        "q.json",
        json.dumps(
            gyroflow_profile(
                fisheye_params={"camera_matrix": [[1, 0, 2], [0, 1, 2], [0, 0, 1]], "distortion_coeffs": [0.1] * 5}
            )
        ),
        ("fisheye_params.distortion_coeffs has 5 values, expected 4",),
    ),
    "gyroflow-matrix": (
        "r.json",
        json.dumps(gyroflow_profile(fisheye_params={"camera_matrix": [1, 2, 3], "distortion_coeffs": [0.1] * 4})),
        ("fisheye_params.camera_matrix[0] is 1, not a list of numbers",),
    ),
    "gyroflow-stretch": (
        "s.json",
        json.dumps(gyroflow_profile(input_horizontal_stretch=1.5)),
        ("input_horizontal_stretch is 1.5: an anamorphic profile is not read",),
    ),
    "gyroflow-nan": (
        "t.json",
        json.dumps(gyroflow_profile(calib_dimension={"w": float("nan"), "h": 1080})),
        ("calib_dimension.w is nan, not a finite number",),
    ),
}


@pytest.mark.parametrize("case", list(BAD_FILES))
def test_bad_files_get_one_line_naming_the_file_and_the_problem(tmp_path: Path, case: str) -> None:
    name, text, fragments = BAD_FILES[case]
    path = write(tmp_path, name, text)
    out = tmp_path / "t.npz"
    result = run("import", path, "-o", out)
    assert_one_line_error(result, str(path), *fragments)
    assert not out.exists()


def test_one_camera_formats_refuse_a_camera_name(tmp_path: Path) -> None:
    path = write(tmp_path, "omni.yaml", boofcv_omni_text())
    result = run("import", path, "-o", tmp_path / "t.npz", "--camera-name", "cam1")
    assert_one_line_error(result, str(path), "a boofcv file holds one camera")
