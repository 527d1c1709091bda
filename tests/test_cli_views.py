"""The perspective, floor and unproject commands, in-process: outputs, and one line per bad input."""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from panomap.simulate import standard_cameras

from helpers import (
    assert_map_sees_like_the_camera,
    assert_one_line_error,
    floor_points,
    perspective_directions,
    run,
    write_cli_inputs,
)

SIZE = (640, 600)
CAMERA = standard_cameras(SIZE, centre=(321.4, 298.2), s=1, phi0=-0.5)["parabolic"]
POSITION = (3.0, 2.0, 2.5)


@pytest.fixture(scope="module")
def work(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder with a fitted table (cam.npz) and an omni-image of its camera (omni.png)."""
    folder = tmp_path_factory.mktemp("views")
    write_cli_inputs(folder, CAMERA, POSITION)
    result = run(
        "fit",
        folder / "lm.csv",
        "-o",
        folder / "cam.npz",
        "--camera",
        *POSITION,
        "--centre",
        *CAMERA.centre,
        "--image-size",
        f"{SIZE[0]}x{SIZE[1]}",
        "--cutoff-radius",
        CAMERA.cutoff_radius,
        "--outer-radius",
        CAMERA.outer_radius,
    )
    assert result.exit_code == 0, result.output + result.stderr
    return folder


def test_perspective_writes_the_view_and_its_maps(work: Path) -> None:
    result = run(
        "perspective",
        work / "cam.npz",
        work / "omni.png",
        "-o",
        work / "persp.png",
        "--yaw-deg",
        -30,
        "--pitch-deg",
        -90,
        "--roll-deg",
        15,
        "--fov-deg",
        150,
        "--size",
        "160x120",
        "--save-map",
        work / "persp.npy",
        "--save-map-pgm",
        work / "persp",
    )
    assert result.exit_code == 0, result.stderr
    assert cv2.imread(str(work / "persp.png")).shape == (120, 160, 3)
    expected = np.load(work / "persp.npy")
    # Against the simulated camera: a sign flip of the roll, or yaw and pitch swapped, fails.
    rays = perspective_directions(math.radians(-30), -math.pi / 2, math.radians(15), math.radians(150), (160, 120))
    assert_map_sees_like_the_camera(expected, CAMERA, rays)
    xmap = cv2.imread(str(work / "persp_x.pgm"), cv2.IMREAD_UNCHANGED)
    assert xmap.dtype == np.uint16 and xmap.shape == (120, 160)
    inside = np.all(np.isfinite(expected), axis=2)
    np.testing.assert_array_equal(xmap[inside], np.rint(expected[..., 0][inside]))
    assert np.all(xmap[~inside] == 65535)


@pytest.mark.parametrize("size_option", [["--size", "300x250"], ["--resolution", 0.02]])
def test_floor_writes_a_map_seen_from_above(work: Path, size_option: list[object]) -> None:
    result = run(
        "floor",
        work / "cam.npz",
        work / "omni.png",
        "-o",
        work / "floor.png",
        "--z",
        0,
        "--x",
        0,
        6,
        "--y",
        -1,
        4,
        *size_option,
        "--save-map",
        work / "floor.npy",
    )
    assert result.exit_code == 0, result.stderr
    saved = np.load(work / "floor.npy")
    assert saved.shape == (250, 300, 2)  # 6 m x 5 m at 0.02 m per pixel, or as given
    # Pixel (224, 100) sees the floor point X = 0 + 224.5 * 0.02, Y = 4 - 100.5 * 0.02, and so on:
    # where the simulated camera sees it.
    assert_map_sees_like_the_camera(saved, CAMERA, floor_points(0, (0, 6), (-1, 4), (300, 250), POSITION))


def read_csv(path: Path) -> list[dict[str, str]]:
    return list(csv.DictReader(io.StringIO(path.read_text())))


def test_unproject_gives_rays_and_floor_points_that_project_back(work: Path) -> None:
    u0, v0 = CAMERA.centre
    pixels = [(u0 + r * math.cos(a), v0 + r * math.sin(a)) for r in (60.0, 130.0, 200.0) for a in (0.3, 2.0, 4.4)]
    # (Radii below 216 px look below the horizon.) Then the centre, a corner, inside the cut-off.
    pixels += [(u0, v0), (5.0, 5.0), (u0 + 10.0, v0)]
    rows = "".join(f"p{k},{u:.6f},{v:.6f},7\n" for k, (u, v) in enumerate(pixels))
    (work / "px.csv").write_text("name,u,v,X\n" + rows)
    result = run("unproject", work / "cam.npz", work / "px.csv", "-o", work / "rays.csv", "--z", 0)
    assert result.exit_code == 0, result.stderr
    assert "9 of 12 pixels in the valid region; 9 rays reach the plane Z = 0" in result.output
    out = read_csv(work / "rays.csv")
    # Input columns pass through, except X, which the output replaces.
    assert list(out[0]) == ["name", "u", "v", "azimuth_deg", "elevation_deg", "X", "Y", "Z"]
    assert all(row[c] == "" for row in out[9:] for c in ("azimuth_deg", "elevation_deg", "X", "Y", "Z"))
    lines = "".join(f"{row['name']},{row['X']},{row['Y']},{row['Z']}\n" for row in out[:9])
    (work / "floor_points.csv").write_text("name,X,Y,Z\n" + lines)
    result = run("project", work / "cam.npz", work / "floor_points.csv", "-o", work / "back.csv")
    assert result.exit_code == 0, result.stderr
    back = np.array([[float(row["u"]), float(row["v"])] for row in read_csv(work / "back.csv")])
    # Round trip through the plane and the table: 6 decimals of metres are 1e-6 m; the CSV keeps
    # 4 decimals of pixels (5e-5 px); the README promises 1e-3 px.
    np.testing.assert_allclose(back, np.array(pixels[:9]), atol=1e-3)
    # Without --z: only the angles; a plane above this ceiling camera is reached by no ray.
    result = run("unproject", work / "cam.npz", work / "px.csv", "-o", work / "rays2.csv")
    assert result.exit_code == 0
    assert list(read_csv(work / "rays2.csv")[0]) == ["name", "u", "v", "X", "azimuth_deg", "elevation_deg"]
    result = run("unproject", work / "cam.npz", work / "px.csv", "-o", work / "rays3.csv", "--z", 5)
    assert "0 rays reach the plane Z = 5" in result.output


PERSPECTIVE = ["--yaw-deg", 10, "--pitch-deg", -30, "--fov-deg", 90, "--size", "100x80"]


@pytest.mark.parametrize(
    # The exit code: 2 for usage (an option click cannot parse, out of range, options that exclude each
    # other), 1 for what depends on the table (a plane the camera cannot see).
    ("command", "options", "message", "exit_code"),
    [
        ("perspective", ["--fov-deg", 0], "the field of view must be more than 0 and less than 180 deg, not 0 deg", 2),
        ("perspective", ["--fov-deg", -20], "not -20 deg", 2),
        ("perspective", ["--fov-deg", 180], "not 180 deg", 2),
        ("perspective", ["--fov-deg", 250], "not 250 deg", 2),
        ("perspective", ["--pitch-deg", 95], "the pitch must be between -90 and 90 deg, not 95 deg", 2),
        ("perspective", ["--fov-deg", "nan"], "'nan' is not a finite number", 2),
        ("floor", ["--x", 3, 3], "the x extent 3..3 is empty", 2),
        ("floor", ["--y", 4, -1], "the y extent 4..-1 is empty", 2),
        ("floor", ["--z", 2.5], "the plane Z = 2.5 is at or above the camera (Z0 = 2.5)", 1),
        ("floor", ["--z", 3], "a camera looking down sees only planes below it", 1),
        ("floor", ["--resolution", 0.05], "--size WxH or --resolution R, one of the two", 2),
        ("floor", ["--size", None], "--size WxH or --resolution R, one of the two", 2),
        ("floor", ["--size", None, "--resolution", -1], "the resolution must be positive", 2),
        ("floor", ["--size", None, "--resolution", 1e-5], "too large", 2),
    ],
)
def test_bad_view_parameters_get_one_line(
    work: Path, command: str, options: list[object], message: str, exit_code: int
) -> None:
    base = {
        "perspective": {"--yaw-deg": [10], "--pitch-deg": [-30], "--fov-deg": [90], "--size": ["100x80"]},
        "floor": {"--z": [0], "--x": [0, 6], "--y": [-1, 4], "--size": ["100x80"]},
    }[command]
    given = dict(base)
    flag = None
    for item in options:
        if isinstance(item, str) and item.startswith("--"):
            flag = item
            given[flag] = []
        elif flag is not None:
            given[flag].append(item)
    args = [a for flag, values in given.items() if None not in values for a in (flag, *values)]
    result = run(command, work / "cam.npz", work / "omni.png", "-o", work / "bad.png", *args)
    assert_one_line_error(result, message, exit_code=exit_code)
    assert not (work / "bad.png").exists()


def test_bad_unproject_input_gets_one_line(work: Path) -> None:
    (work / "nouv.csv").write_text("name,x,y\na,1,2\n")
    result = run("unproject", work / "cam.npz", work / "nouv.csv", "-o", work / "r.csv")
    assert_one_line_error(result, "nouv.csv: the CSV lacks the column(s) u,v")
    (work / "text.csv").write_text("u,v\n1,two\n")
    result = run("unproject", work / "cam.npz", work / "text.csv", "-o", work / "r.csv")
    assert_one_line_error(result, "text.csv: row 2, v is not a number")
    result = run("unproject", work / "none.npz", work / "text.csv", "-o", work / "r.csv")
    assert_one_line_error(result, "none.npz: no such table file")
    assert not (work / "r.csv").exists()


def test_pgm_prefix_in_a_missing_folder_is_refused_before_writing(work: Path) -> None:
    result = run(
        "perspective",
        work / "cam.npz",
        work / "omni.png",
        "-o",
        work / "p2.png",
        *PERSPECTIVE,
        "--save-map-pgm",
        work / "nowhere" / "m",
    )
    assert_one_line_error(result, "m_x.pgm: its folder does not exist")
    assert not (work / "p2.png").exists()
