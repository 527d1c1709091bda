"""Issue 44: calibration files read within bounds, in the forms their tools write, and the interop edges.

Every bad file gets one line naming it and exit code 1, and no table; files are small and synthetic.
"""

from __future__ import annotations

import dataclasses
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from panomap import export_calibration, import_calibration
from panomap.errors import PanomapError
from panomap.interop.readers.yaml_text import brief, load_yaml

from helpers import assert_one_line_error, run

SRC = Path(__file__).resolve().parents[1] / "src"
SMALL = (256, 64)  # table size: enough to check the equations, fast to build
TOLERANCE_PX = 0.01


def world_angles_of_opencv(rays: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Table azimuth and elevation (rad) of rays in the calibration's OpenCV frame, looking down."""
    world = rays * np.array([1.0, -1.0, -1.0])
    theta = np.mod(np.arctan2(world[..., 1], world[..., 0]), 2 * np.pi)
    return theta, np.arctan2(world[..., 2], np.hypot(world[..., 0], world[..., 1]))


def fan(max_angle_deg: float, min_angle_deg: float = 1.0) -> np.ndarray:
    """Rays (n, 3) from ``min`` to ``max`` deg off the axis, all around."""
    a = np.radians(np.linspace(min_angle_deg, max_angle_deg, 40))[:, None]
    phi = np.linspace(0, 2 * np.pi, 36, endpoint=False)[None, :]
    return np.stack(np.broadcast_arrays(np.sin(a) * np.cos(phi), np.sin(a) * np.sin(phi), np.cos(a)), -1).reshape(-1, 3)


def table_error(table, rays: np.ndarray, uv: np.ndarray) -> float:
    got = table.sample(*world_angles_of_opencv(rays)).astype(np.float64)
    assert np.all(np.isfinite(got)), "the table misses rays it should hold"
    return float(np.max(np.hypot(*(got - uv).T)))


def fov_project(rays: np.ndarray, fx, fy, cx, cy, omega, colmap_series: bool = False) -> np.ndarray:
    """The FOV model (Devernay & Faugeras); below omega 0.01, COLMAP's series as its models.h writes it."""
    a, b = rays[:, 0] / rays[:, 2], rays[:, 1] / rays[:, 2]
    r = np.hypot(a, b)
    if colmap_series:
        factor = omega**2 * r**2 / 3 - omega**2 / 12 + 1
    else:
        factor = np.arctan(2 * r * math.tan(omega / 2)) / (omega * r)
    return np.stack([fx * a * factor + cx, fy * b * factor + cy], -1)


KB_CAM = (
    "cam0:\n  camera_model: pinhole\n  intrinsics: [300.0, 300.0, 320.0, 240.0]\n"
    "  distortion_model: equidistant\n  distortion_coeffs: [0.01, 0.0, 0.0, 0.0]\n  resolution: [640, 480]\n"
)
K_MATRIX = "!!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [300., 0., 320., 0., 300., 240., 0., 0., 1.]\n"
D_MATRIX = "!!opencv-matrix\n   rows: 1\n   cols: 4\n   dt: d\n   data: [0.01, 0., 0., 0.]\n"


def opencv_file(**values: str) -> str:
    return "%YAML:1.0\n---\n" + "".join(f"{key}: {value}\n" for key, value in values.items())


# ----------------------------------------------------------------------------- memory and nesting bounds


def alias_bomb(levels: int = 9) -> str:
    """A camchain of about 500 bytes whose intrinsics expand to 10^9 values through YAML aliases."""
    lines = ["a0: &a0 [" + ",".join("x" * 10) + "]"]
    for level in range(1, levels):
        lines.append(f"a{level}: &a{level} [" + ",".join([f"*a{level - 1}"] * 10) + "]")
    lines.append(
        f"cam0:\n  camera_model: pinhole\n  intrinsics: *a{levels - 1}\n  distortion_model: none\n"
        "  resolution: [640, 480]"
    )
    return "\n".join(lines) + "\n"


def test_a_yaml_alias_bomb_is_refused_in_bounded_memory(tmp_path: Path) -> None:
    path = tmp_path / "camchain.yaml"
    path.write_text(alias_bomb())
    assert len(path.read_bytes()) < 600
    # In its own process, under a 1.5 GB address-space limit (before: over 6 GB, formatting the value).
    script = (
        "import resource, sys; resource.setrlimit(resource.RLIMIT_AS, (1536 << 20, 1536 << 20)); "
        "from panomap.cli.app import main; sys.argv = ['panomap', 'import', sys.argv[1], '-o', sys.argv[2]]; main()"
    )
    out = tmp_path / "cam.npz"
    result = subprocess.run(
        [sys.executable, "-c", script, str(path), str(out)],
        capture_output=True,
        text=True,
        timeout=120,
        env=dict(os.environ, PYTHONPATH=str(SRC)),
    )
    lines = result.stderr.strip().splitlines()
    assert result.returncode == 1, result.stderr[-2000:]
    assert len(lines) == 1 and "aliases expand to more than" in lines[0] and str(path) in lines[0], lines[-3:]
    assert not out.exists()


def test_a_few_aliases_as_pyyaml_writes_them_still_load(tmp_path: Path) -> None:
    shared = [640, 480]  # PyYAML writes a list met twice as an anchor and an alias
    text = yaml.safe_dump({"cam0": yaml.safe_load(KB_CAM)["cam0"] | {"resolution": shared}, "cam1": {"x": shared}})
    assert "&id001" in text and "*id001" in text
    assert import_calibration_small(tmp_path, text).image_size == (640, 480)


def import_calibration_small(tmp_path: Path, text: str, name: str = "calib.yaml", size=SMALL, **kwargs):
    path = tmp_path / name
    path.write_text(text)
    return import_calibration(path, size=size, **kwargs)


def test_brief_never_walks_a_whole_expanded_value() -> None:
    value: list = ["x"] * 10
    for _ in range(9):
        value = [value] * 10  # 10^10 values as str() would write them
    text = brief(value)
    assert len(text) <= 70 and text.startswith("[[[[")
    assert load_yaml(alias_bomb(levels=4), "x.yaml")["cam0"]["intrinsics"][0][0][0] == list("x" * 10)
    with pytest.raises(PanomapError, match="aliases expand to more than"):
        load_yaml(alias_bomb(levels=6), "x.yaml")


@pytest.mark.parametrize(
    ("name", "text", "fragment"),
    [
        ("deep.yaml", "cam0: " + "[" * 50000 + "]" * 50000 + "\ncamera_model: x\n", "nested more than 64 levels"),
        ("deep_cv.yaml", "%YAML:1.0\n---\nK: " + "[" * 50000 + "]" * 50000 + "\n", "not a readable OpenCV"),
        ("big.yaml", KB_CAM + "#" + "x" * 1_100_000 + "\n", "more than a calibration file holds"),
    ],
)
def test_deep_or_huge_yaml_gets_one_line(tmp_path: Path, name: str, text: str, fragment: str) -> None:
    path = tmp_path / name
    path.write_text(text)
    out = tmp_path / "cam.npz"
    result = run("import", path, "-o", out, *(["--format", "opencv"] if "cv" in name else []))
    assert_one_line_error(result, str(path), fragment)
    assert not out.exists()


# ----------------------------------------------------------------------------- numbers in every format

BIG = "1" + "0" * 400
OCAM = (
    "#polynomial coefficients for the DIRECT mapping function\n"
    "5 -2.063866e+02 0.000000e+00 2.165610e-03 -4.495456e-06 1.810639e-08\n"
    "#polynomial coefficients for the inverse mapping function\n3 293.0 151.5 -11.1\n"
    "#center\n241.0 385.7\n#affine\n1.0 0.0 0.0\n#image size\n480 748\n"
)
COLMAP = "1 OPENCV_FISHEYE 640 480 300 300 320.5 240.5 0.01 0 0 0\n"
OPENCV = opencv_file(K=K_MATRIX, D=D_MATRIX, image_width="640", image_height="480")


@pytest.mark.parametrize(
    ("text", "bad"),
    [
        (KB_CAM, ("300.0, 300.0, 320.0", ".nan, 300.0, 320.0")),
        (KB_CAM, ("300.0, 300.0, 320.0", ".inf, 300.0, 320.0")),
        (KB_CAM, ("300.0, 300.0, 320.0", f"{BIG}, 300.0, 320.0")),
        (KB_CAM, ("[640, 480]", f"[{BIG}, 480]")),
        (KB_CAM, ("[640, 480]", f"[{'9' * 5000}, 480]")),
        (OCAM, ("241.0 385.7", "nan 385.7")),
        (OCAM, ("480 748", f"480 {BIG}")),
        (OCAM, ("5 -2.06", "inf -2.06")),
        (COLMAP, ("300 300", "nan 300")),
        (COLMAP, ("300 300", f"{BIG} 300")),
        (COLMAP, ("640 480", f"{BIG} 480")),
        (OPENCV, ("[300., 0.", "[.nan, 0.")),
        (OPENCV, ("[300., 0.", "[1e400, 0.")),
        (OPENCV, ("image_width: 640", f"image_width: {BIG}")),
        (OPENCV, ("image_width: 640", f"image_width: -{BIG}")),
    ],
)
def test_nan_inf_and_400_digit_numbers_get_one_line(tmp_path: Path, text: str, bad: tuple[str, str]) -> None:
    assert bad[0] in text
    path = tmp_path / "calib.txt"
    path.write_text(text.replace(*bad))
    out = tmp_path / "cam.npz"
    result = run("import", path, "-o", out)
    assert_one_line_error(result, str(path))
    assert not out.exists()


# ----------------------------------------------------------------------------- OpenCV FileStorage forms


@pytest.mark.parametrize(
    "values",
    [
        {"K": K_MATRIX, "D": D_MATRIX, "image_size": "[640, 480]"},  # image_size as a plain list
        {"K": "[300., 0., 320., 0., 300., 240., 0., 0., 1.]", "D": "[0.01, 0., 0., 0.]", "imageSize": "[640, 480]"},
        {"M": K_MATRIX, "D": D_MATRIX, "image_width": "640", "image_height": "480"},
        {  # the calibration tutorial's out_camera_data.yml
            "image_Width": "640",
            "image_Height": "480",
            "Camera_Matrix": K_MATRIX,
            "Distortion_Coefficients": D_MATRIX,
            "fisheye_model": "1",
        },
    ],
)
def test_opencv_files_in_their_documented_forms(tmp_path: Path, values: dict[str, str]) -> None:
    table = import_calibration_small(tmp_path, opencv_file(**values))
    assert table.image_size == (640, 480)
    assert table.info["import"]["model"] == "opencv-fisheye"
    assert table.info["import"]["parameters"]["fx"] == 300.0


MEI = {"xi": 1.2, "k": (300.0, 300.0, 320.0, 240.0)}


def mei_project(rays: np.ndarray, xi: float, fx, fy, cx, cy) -> np.ndarray:
    unit = rays / np.linalg.norm(rays, axis=-1, keepdims=True)
    x, y = unit[:, 0] / (unit[:, 2] + xi), unit[:, 1] / (unit[:, 2] + xi)
    return np.stack([fx * x + cx, fy * y + cy], -1)


@pytest.mark.parametrize(
    "values",
    [
        {"K": K_MATRIX, "D": D_MATRIX.replace("0.01", "0."), "xi": "[1.2]"},  # xi as a list
        {  # OpenCV's omnidir stereo sample: its first camera
            "camera_matrix_1": K_MATRIX,
            "distortion_coefficients_1": D_MATRIX.replace("0.01", "0."),
            "xi_1": "1.2",
            "camera_matrix_2": K_MATRIX.replace("300.", "310."),
            "xi_2": "1.5",
        },
    ],
)
def test_opencv_omnidir_forms_need_the_image_size(tmp_path: Path, values: dict[str, str]) -> None:
    path = tmp_path / "omnidir.yaml"
    path.write_text(opencv_file(**values))
    out = tmp_path / "cam.npz"
    # No image size in an omnidir file: the table would span the model's whole range (past the image).
    result = run("import", path, "-o", out)
    assert_one_line_error(result, str(path), "no image size", "--image-size")
    assert not out.exists()
    result = run("import", path, "-o", out, "--image-size", "640x480", "--table-size", "256x64")
    assert result.exit_code == 0, result.stderr
    table = import_calibration(path, image_size=(640, 480), size=SMALL)
    assert table.info["import"]["model"] == "mei"
    rays = fan(60.0)
    assert table_error(table, rays, mei_project(rays, 1.2, 300.0, 300.0, 320.0, 240.0)) < TOLERANCE_PX
    assert table.outer_radius < math.hypot(320.5, 240.5) + 1


def test_the_calibrations_image_limit_is_the_image_readers() -> None:
    from panomap.interop.readers import base
    from panomap.io import images

    assert base.MAX_IMAGE_PIXELS == images.MAX_IMAGE_PIXELS


def test_image_size_option_is_checked(tmp_path: Path) -> None:
    path = tmp_path / "calib.yaml"
    path.write_text(OPENCV)
    result = run("import", path, "-o", tmp_path / "cam.npz", "--image-size", "0x480")
    assert_one_line_error(result, "--image-size", exit_code=2)
    result = run("import", path, "-o", tmp_path / "cam.npz", "--image-size", "800x600")
    assert_one_line_error(result, str(path), "640 x 480 images, the image is 800 x 600")


@pytest.mark.parametrize(
    "text",
    [
        "%YAML:1.0\n---\nK: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [300., 0., 320., 0.\n",
        "%YAML:1.0\n---\nK: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [1., 2.]\nD: [0, 0, 0, 0]\n",
        "%YAML:1.0\n---\nK: [[300., 0.], [320.]]\nD: [0, 0, 0, 0]\n",
        "%YAML:1.0\n---\nK: {a: 1}\nD: [0, 0, 0, 0]\n",
        "%YAML:1.0\n---\n- K\n- opencv-matrix\n",
    ],
)
def test_malformed_opencv_files_get_one_line(tmp_path: Path, text: str) -> None:
    path = tmp_path / "calib.yaml"
    path.write_text(text)
    out = tmp_path / "cam.npz"
    result = run("import", path, "-o", out, "--format", "opencv")
    assert_one_line_error(result, str(path))
    assert not out.exists()


# ----------------------------------------------------------------------------- Kalibr


def test_kalibr_files_beginning_with_opencvs_yaml_directive_are_recognised(tmp_path: Path) -> None:
    table = import_calibration_small(tmp_path, "%YAML:1.0\n" + KB_CAM)
    assert table.info["import"]["format"] == "kalibr"


def test_kalibr_fov_distortion_is_read(tmp_path: Path) -> None:
    text = KB_CAM.replace("equidistant", "fov").replace("[0.01, 0.0, 0.0, 0.0]", "[0.9]")
    table = import_calibration_small(tmp_path, text, size=(720, 512))
    rays = fan(35.0)
    assert table_error(table, rays, fov_project(rays, 300.0, 300.0, 320.0, 240.0, 0.9)) < TOLERANCE_PX
    # Kalibr's FOV keeps its closed form at small w (COLMAP's switches to a series).
    table = import_calibration_small(tmp_path, text.replace("[0.9]", "[0.005]"), size=(720, 512))
    assert table_error(table, rays, fov_project(rays, 300.0, 300.0, 320.0, 240.0, 0.005)) < TOLERANCE_PX


def test_kalibr_eucm_alpha_of_one_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "camchain.yaml"
    path.write_text(
        "cam0:\n  camera_model: eucm\n  intrinsics: [1.0, 1.1, 300.0, 300.0, 320.0, 240.0]\n"
        "  distortion_model: none\n  distortion_coeffs: []\n  resolution: [640, 480]\n"
    )
    result = run("import", path, "-o", tmp_path / "cam.npz")
    assert_one_line_error(result, str(path), "alpha is 1", "below 1")


def test_kalibr_export_names_its_rostopic(tmp_path: Path) -> None:
    table = import_calibration_small(tmp_path, KB_CAM)
    out = tmp_path / "camchain.yaml"
    export_calibration(table, out, "kalibr-equidistant")
    cam = yaml.safe_load(out.read_text())["cam0"]
    assert cam["rostopic"] == "/cam0/image_raw" and cam["cam_overlaps"] == []


# ----------------------------------------------------------------------------- COLMAP


def test_colmap_eucm_table_stops_before_the_image_plane(tmp_path: Path) -> None:
    # alpha 0.6, beta 1.1: the model itself sees 117.7 deg from the axis; COLMAP refuses z <= 0.
    table = import_calibration_small(tmp_path, "1 EUCM 1200 1200 300 300 600.5 600.5 0.6 1.1\n", "cameras.txt")
    assert table.info["import"]["model"] == "colmap-eucm"
    assert table.elevation_range[1] <= 1e-9  # looking down: 90 deg from the axis is elevation 0
    assert table.unproject(np.array([600.0, 600.0])) is not None


def test_colmap_fov_below_omega_001_follows_colmaps_series(tmp_path: Path) -> None:
    table = import_calibration_small(
        tmp_path, "1 FOV 2000 2000 150 150 1000.5 1000.5 0.009\n", "cameras.txt", size=(720, 1024)
    )
    rays = fan(80.0)
    expected = fov_project(rays, 150.0, 150.0, 1000.0, 1000.0, 0.009, colmap_series=True)
    assert table_error(table, rays, expected) < TOLERANCE_PX
    # The closed form differs by pixels there: the test tells the two apart.
    assert table_error(table, rays, fov_project(rays, 150.0, 150.0, 1000.0, 1000.0, 0.009)) > 0.5


# ----------------------------------------------------------------------------- export of an edited table


def test_a_solver_failure_in_export_is_one_line(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    table_path = tmp_path / "cam.npz"
    path = tmp_path / "camchain.yaml"
    path.write_text(KB_CAM)
    assert run("import", path, "-o", table_path, "--table-size", "256x64").exit_code == 0

    def failing(*args: object, **kwargs: object) -> None:
        raise np.linalg.LinAlgError("SVD did not converge in Linear Least Squares")

    monkeypatch.setattr(np.linalg, "lstsq", failing)
    out = tmp_path / "calib_results.txt"
    result = run("export", table_path, "-o", out, "--format", "ocam")
    assert_one_line_error(result, str(table_path), "cannot be fitted to this table", "LinAlgError")
    assert not out.exists()


@pytest.mark.slow  # 3-4 s of set-up on two cores: the fast subset keeps within its 3 minutes
def test_an_edited_table_no_camera_makes_is_refused_in_export(tmp_path: Path) -> None:
    table = import_calibration_small(tmp_path, KB_CAM)
    rng = np.random.default_rng(1)
    edited = dataclasses.replace(table, entries=rng.uniform(0, 480, table.entries.shape).astype(np.float32))
    with pytest.raises(PanomapError, match="entries are not a camera's"):
        export_calibration(edited, tmp_path / "calib_results.txt", "ocam")
    assert not (tmp_path / "calib_results.txt").exists()


@pytest.mark.parametrize(
    ("text", "fragment"),
    [
        ("1 FOV 640 480 300 300 320.5 240.5 3.2\n", "colmap-fov: omega must be in (-pi, pi), not 3.2"),
        (KB_CAM.replace("equidistant", "fov").replace("[0.01, 0.0, 0.0, 0.0]", "[3.2]"), "fov: omega must be in"),
        (KB_CAM.replace("[0.01, 0.0", "[-100000.0, 0.0"), "image radius stops growing 0.37 px from its principal"),
    ],
)
def test_parameters_that_make_no_camera_get_one_line(tmp_path: Path, text: str, fragment: str) -> None:
    # Before: a table of radii 0..0.5 px was written.
    path = tmp_path / "calib.txt"
    path.write_text(text)
    out = tmp_path / "cam.npz"
    result = run("import", path, "-o", out)
    assert_one_line_error(result, str(path), fragment)
    assert not out.exists()
