"""The command line, in-process: what it writes, and one clear line for every bad input."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from panomap.calibrate.landmarks.pairs import Landmarks, landmarks_to_csv
from panomap.simulate import standard_cameras
from panomap.table.file import load_table

from helpers import (
    assert_map_sees_like_the_camera,
    assert_one_line_error,
    cylinder_points,
    panorama_directions,
    plane_points,
    run,
    write_cli_inputs,
)

SIZE = (640, 600)
CAMERA = standard_cameras(SIZE, centre=(321.4, 298.2), s=1, phi0=-0.5)["parabolic"]
POSITION = (3.0, 2.0, 2.5)
# The table's elevation range: the camera's, as fit_table gives its radii.
ELEVATIONS = CAMERA.elevation_range


@pytest.fixture
def work(tmp_path: Path) -> Path:
    write_cli_inputs(tmp_path, CAMERA, POSITION)
    return tmp_path


def fit_table(work: Path, *extra: object) -> Path:
    result = run(
        "fit",
        work / "lm.csv",
        "-o",
        work / "cam.npz",
        "--camera",
        *POSITION,
        "--centre",
        *CAMERA.centre,
        "--image",
        work / "omni.png",
        "--cutoff-radius",
        CAMERA.cutoff_radius,
        "--outer-radius",
        CAMERA.outer_radius,
        *extra,
    )
    assert result.exit_code == 0, result.output + result.stderr
    return work / "cam.npz"


def test_fit_writes_a_table_and_reports_residuals(work: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import matplotlib.pyplot as plt

    figures = []
    close = plt.close
    monkeypatch.setattr(plt, "close", lambda figure: (figures.append(figure), close(figure)))
    table_path = fit_table(work, "--plot", work / "fit.png")
    out = run("info", table_path).output
    assert "azimuth mapping: s = +1, phi0 = -28.6479 deg" in out
    assert "residuals: RMS 0.000 px" in out
    meta = json.loads(run("info", table_path, "--json").output)
    # A parabolic mirror's law, r = gamma tan(alpha / 2), is both the mirrors' (unified, xi = 1) and the
    # stereographic fisheye's (fisheye, k = -1/2); with no cut-off disc given, the fisheye family comes first.
    radial = meta["model"]["radial"]
    assert radial["kind"] == "fisheye" and radial["coefficients"][1] == pytest.approx(-0.5, abs=1e-6)
    assert meta["image_size"] == list(SIZE)
    assert meta["info"]["sources"]["centre"] == "given"
    assert len(meta["info"]["fit"]["landmarks"]) == 12
    assert cv2.imread(str(work / "fit.png")).shape[2] == 3
    # The plot (the paper's Fig. 7b) against the simulated camera: the landmarks at their true
    # elevations and image radii, and f_r through the camera's radial law.
    (figure,) = figures
    top = figure.axes[0]
    rows = np.loadtxt(work / "lm.csv", delimiter=",", skiprows=1, usecols=(1, 2, 3, 4, 5))
    offsets = rows[:, 2:] - np.array(POSITION)
    elevation_deg = np.degrees(np.arctan2(offsets[:, 2], np.hypot(offsets[:, 0], offsets[:, 1])))
    radius = np.hypot(rows[:, 0] - CAMERA.centre[0], rows[:, 1] - CAMERA.centre[1])
    (marks,) = [line for line in top.get_lines() if line.get_marker() == "+"]
    order = np.argsort(elevation_deg)
    plotted = np.argsort(np.asarray(marks.get_xdata()))
    np.testing.assert_allclose(np.asarray(marks.get_xdata())[plotted], elevation_deg[order], atol=1e-9)
    np.testing.assert_allclose(np.asarray(marks.get_ydata())[plotted], radius[order], atol=1e-9)
    curve = next(line for line in top.get_lines() if str(line.get_label()).startswith("f_r"))
    rho = np.radians(np.asarray(curve.get_xdata(), dtype=float))
    truth = CAMERA.project(np.stack([np.cos(rho), np.zeros_like(rho), np.sin(rho)], axis=-1))
    # Exact landmarks and the camera's own model family (unified): the curve is the law wherever
    # the camera sees (measured: within 1e-9 px; the bar leaves room for other BLAS builds).
    seen = np.isfinite(truth[:, 0])
    assert seen.mean() > 0.95
    true_radius = np.hypot(truth[seen, 0] - CAMERA.centre[0], truth[seen, 1] - CAMERA.centre[1])
    np.testing.assert_allclose(np.asarray(curve.get_ydata(), dtype=float)[seen], true_radius, atol=1e-6)


def test_fit_paper_model_and_azimuth_as_printed(work: Path) -> None:
    table = load_table(fit_table(work, "--model", "paper", "--azimuth", "paper", "--size", "720x90"))
    assert table.model.radial.kind == "paper" and table.size == (720, 90)
    assert (table.model.s, table.model.phi0) == (1, 0.0)


def test_views_write_images_and_the_maps_they_used(work: Path) -> None:
    table_path = fit_table(work)
    result = run(
        "plane",
        table_path,
        work / "omni.png",
        "-o",
        work / "plane.png",
        "--distance",
        2,
        "--plane-width",
        2,
        "--band",
        -2.4,
        0.2,
        "--azimuth-deg",
        40,
        "--size",
        "200x150",
        "--save-map",
        work / "plane.npy",
    )
    assert result.exit_code == 0, result.stderr
    saved = np.load(work / "plane.npy")
    assert saved.dtype == np.float32 and saved.shape == (150, 200, 2)
    # Against the simulated camera: a sign flip of the azimuth, or a band upside down, fails.
    assert_map_sees_like_the_camera(saved, CAMERA, plane_points(2, 2, (-2.4, 0.2), math.radians(40), (200, 150)))
    views = [
        ("panorama", ["--size", "360x60", "--start-deg", 90], panorama_directions((360, 60), math.pi / 2, ELEVATIONS)),
        (
            "cylinder",
            ["--distance", 2, "--band", -2, 0.5, "--size", "360x80", "--interp", "cubic"],
            cylinder_points(2, (-2, 0.5), (360, 80)),
        ),
    ]
    for command, options, points in views:
        out, map_path = work / f"{command}.png", work / f"{command}.npy"
        result = run(command, table_path, work / "omni.png", "-o", out, *options, "--save-map", map_path)
        assert result.exit_code == 0, result.stderr
        assert_map_sees_like_the_camera(np.load(map_path), CAMERA, points)
        # The image holds the test pattern where the camera projects each pixel: blue u mod 256, green
        # v mod 256. The pattern is linear between its wraps, which linear and cubic interpolation keep:
        # only the rounding to 8 bits remains (measured 0.5013 grey levels at most).
        truth = CAMERA.project(points)
        image = cv2.imread(str(out)).astype(np.float64)
        pattern = np.mod(truth, 256)
        away = np.all((pattern > 3) & (pattern < 252), axis=-1)  # the 4 x 4 cubic kernel crosses no wrap
        assert away.mean() > 0.9
        np.testing.assert_allclose(image[..., :2][away], pattern[away], atol=0.6)


def test_an_image_a_viewer_would_turn_is_taken_as_stored_with_a_warning(work: Path) -> None:
    """EXIF orientation 6 (a phone held upright): viewers show the image turned 90 deg, panomap takes the pixels
    as stored (the table belongs to the sensor's grid) and says so once; the view is that of the same pixels
    without the tag."""
    from PIL import Image

    table_path = fit_table(work)
    exif = Image.Exif()
    exif[0x0112] = 6
    with Image.open(work / "omni.png") as image:
        image.save(work / "turned.png", exif=exif)
    plain = run("panorama", table_path, work / "omni.png", "-o", work / "plain.png", "--size", "256x64")
    turned = run("panorama", table_path, work / "turned.png", "-o", work / "turned_view.png", "--size", "256x64")
    assert plain.exit_code == turned.exit_code == 0, plain.stderr + turned.stderr
    assert plain.stderr == ""
    assert turned.stderr.splitlines() == [
        f"panomap: warning: {work / 'turned.png'}: its EXIF orientation (6) asks viewers to show it turned 90 deg "
        "clockwise: panomap takes the pixels as stored, so measure landmarks in the image as stored, not as a "
        "viewer shows it"
    ]
    np.testing.assert_array_equal(cv2.imread(str(work / "turned_view.png")), cv2.imread(str(work / "plain.png")))
    assert "EXIF orientation (6)" in run("centre", work / "turned.png").stderr


def test_project_writes_pixels_and_leaves_invisible_points_empty(work: Path) -> None:
    table_path = fit_table(work)
    points = np.array([[4.0, 2.5, 0.0], [1.0, 1.0, 1.0], [3.0, 2.0, 9.0]])
    (work / "pts.csv").write_text("name,X,Y,Z\n" + "".join(f"p{k},{x},{y},{z}\n" for k, (x, y, z) in enumerate(points)))
    result = run("project", table_path, work / "pts.csv", "-o", work / "px.csv")
    assert result.exit_code == 0, result.stderr
    lines = (work / "px.csv").read_text().splitlines()
    assert lines[0] == "name,X,Y,Z,u,v"
    assert lines[3].endswith(",,")  # straight up: not visible
    truth = CAMERA.project(points[:2] - np.array(POSITION))
    got = np.array([[float(x) for x in line.split(",")[4:]] for line in lines[1:3]])
    # Exact landmarks and an exact model family: only the table's float32 and bilinear error remain.
    np.testing.assert_allclose(got, truth, atol=0.01)
    # '-': the same CSV on standard output (to pipe it), the summary on standard error, no file named '-'.
    piped = run("project", table_path, work / "pts.csv", "-o", "-")
    assert piped.exit_code == 0, piped.stderr
    assert piped.stdout == (work / "px.csv").read_text()
    assert piped.stderr == "wrote standard output (2 of 3 points visible)\n"
    # A semicolon file with decimal commas gets its pixels back in its own separators and decimal mark.
    (work / "pts_de.csv").write_text((work / "pts.csv").read_text().replace(",", ";").replace(".", ","))
    german = run("project", table_path, work / "pts_de.csv", "-o", "-")
    assert german.exit_code == 0, german.stderr
    assert german.stdout == piped.stdout.replace(",", ";").replace(".", ",")
    (work / "seen.csv").write_text("\n".join(lines[:3]) + "\n")
    rays = run("unproject", table_path, work / "seen.csv", "-o", "-")
    assert rays.exit_code == 0, rays.stderr
    assert rays.stdout.splitlines()[0] == "name,X,Y,Z,u,v,azimuth_deg,elevation_deg"
    assert len(rays.stdout.splitlines()) == 3
    assert rays.stderr == "wrote standard output (2 of 2 pixels in the valid region)\n"
    assert not Path("-").exists() and not (work / "-").exists()


def test_a_json_files_camera_is_used_and_a_different_camera_option_replaces_it_with_a_warning(work: Path) -> None:
    from panomap.calibrate.landmarks.pairs import landmarks_to_json, read_landmarks

    pairs = read_landmarks(work / "lm.csv")
    (work / "lm.json").write_text(
        landmarks_to_json(type(pairs)(pairs.pixels, pairs.world, pairs.names, (3.1, 2.0, 2.5)))
    )
    common = ["--image", work / "omni.png", "--centre", *CAMERA.centre, "--tilt", "none", "--camera-sigma", 0]
    from_file = run("fit", work / "lm.json", "-o", work / "a.npz", *common)
    assert from_file.exit_code == 0, from_file.stderr
    assert "--camera" not in from_file.stderr
    assert load_table(work / "a.npz").camera_position == (3.1, 2.0, 2.5)
    replaced = run("fit", work / "lm.json", "-o", work / "b.npz", "--camera", *POSITION, *common)
    assert replaced.exit_code == 0, replaced.stderr
    assert f"panomap: warning: --camera (3, 2, 2.5) is used, not the camera in {work / 'lm.json'} (3.1, 2, 2.5)" in (
        replaced.stderr
    )
    assert load_table(work / "b.npz").camera_position == POSITION


def _lossless_video(path: Path, image: np.ndarray, frames: int = 3, step_px: int = 0) -> None:
    """A lossless video (FFV1 in Matroska, 25 fps) whose frame k is ``image`` (H, W, 3) BGR moved right by
    ``k * step_px`` px."""
    import av

    with av.open(str(path), "w") as container:
        stream = container.add_stream("ffv1", rate=25)
        stream.width, stream.height, stream.pix_fmt = image.shape[1], image.shape[0], "bgr0"
        for k in range(frames):
            moved = np.roll(image, k * step_px, axis=1)
            for packet in stream.encode(av.VideoFrame.from_ndarray(moved, format="bgr24")):
                container.mux(packet)
        for packet in stream.encode():
            container.mux(packet)


@pytest.mark.slow
def test_a_video_serves_where_one_omni_image_is_taken_and_views_point_to_panomap_video(work: Path) -> None:
    from panomap.simulate import load_room, render

    omni = render(load_room(), CAMERA, supersample=1)
    cv2.imwrite(str(work / "room.png"), omni)
    _lossless_video(work / "room.mkv", omni)
    # centre: the same circles as on the frame itself, and a note that the first frame was used.
    from_image = run("centre", work / "room.png", "--json")
    from_video = run("centre", work / "room.mkv", "--json")
    assert from_video.exit_code == 0, from_video.stderr
    assert json.loads(from_video.stdout) == json.loads(from_image.stdout)
    assert f"panomap: note: {work / 'room.mkv'} is a video: its first frame is used" in from_video.stderr
    # fit --image: the same table.
    common = ["--camera", *POSITION, "--tilt", "none", "--camera-sigma", 0]
    assert run("fit", work / "lm.csv", "-o", work / "a.npz", "--image", work / "room.png", *common).exit_code == 0
    video_fit = run("fit", work / "lm.csv", "-o", work / "b.npz", "--image", work / "room.mkv", *common)
    assert video_fit.exit_code == 0, video_fit.stderr
    np.testing.assert_array_equal(load_table(work / "a.npz").entries, load_table(work / "b.npz").entries)
    # --frame-time: the frame at that time (frame 3 of 25 fps, the image moved 6 px right each frame).
    _lossless_video(work / "moving.mkv", omni, frames=6, step_px=6)
    later = run("centre", work / "moving.mkv", "--json", "--frame-time", 0.12)
    assert later.exit_code == 0, later.stderr
    assert "its frame at 0.12 s is used" in later.stderr
    shift = np.subtract(json.loads(later.stdout)["centre"], json.loads(from_image.stdout)["centre"])
    np.testing.assert_allclose(shift, [18.0, 0.0], atol=0.05)
    past = run("centre", work / "moving.mkv", "--frame-time", 9)
    assert_one_line_error(past, "moving.mkv: it has no frame at or after 9 s")
    # A view of a video: one line pointing to panomap video, and no output.
    view = run("panorama", work / "a.npz", work / "room.mkv", "-o", work / "p.png")
    assert_one_line_error(view, "room.mkv: it is a video: unwarp it with panomap video")
    assert not (work / "p.png").exists()


@pytest.mark.parametrize(
    ("mistake", "hint"),
    [
        ("y_up", "with Y as up they would be: a Y-up world frame needs its points (and the camera) as (x, -z, y)"),
        ("half_size", "times 2 they would be: were they measured on a copy of the image smaller by 2 times?"),
    ],
)
def test_landmarks_given_in_another_frame_or_scale_get_a_hint(work: Path, mistake: str, hint: str) -> None:
    from panomap.calibrate.landmarks.pairs import read_landmarks

    pairs = read_landmarks(work / "lm.csv")
    pixels, world, camera = pairs.pixels, pairs.world, POSITION
    if mistake == "y_up":  # (x, y, z) = (X, Z, -Y): Y up
        world = np.stack([world[:, 0], world[:, 2], -world[:, 1]], axis=-1)
        camera = (POSITION[0], POSITION[2], -POSITION[1])
    else:
        pixels = pixels / 2
    (work / "wrong.csv").write_text(landmarks_to_csv(Landmarks(pixels, world, pairs.names)))
    result = run(
        "fit",
        work / "wrong.csv",
        "-o",
        work / "t.npz",
        "--camera",
        *camera,
        "--image",
        work / "omni.png",
        "--centre",
        *CAMERA.centre,
        "--cutoff-radius",
        CAMERA.cutoff_radius,
        "--outer-radius",
        CAMERA.outer_radius,
    )
    assert_one_line_error(result, "cannot tell from the landmarks whether the camera looks down or up", hint)
    assert not (work / "t.npz").exists()


def test_semicolon_and_tab_files_with_decimal_commas_fit_as_the_comma_file_does(work: Path) -> None:
    # A spreadsheet where the decimal mark is a comma writes "name;u;v;X;Y;Z" rows of "door;412,5;...".
    first = json.loads(run("info", fit_table(work), "--json").output)["model"]
    comma = (work / "lm.csv").read_text()
    for separator in (";", "\t"):
        (work / "lm.csv").write_text(comma.replace(",", separator).replace(".", ","))
        again = json.loads(run("info", fit_table(work), "--json").output)["model"]
        assert again == first, separator


BAD_LANDMARKS = {
    "no_columns": ("a,b,c\n1,2,3\n", "lacks the column(s) u,v,X,Y,Z"),
    "too_few": ("u,v,X,Y,Z\n" + "1,2,3,4,0\n" * 4, "only 4 landmark(s); at least 5"),
    "nan": ("u,v,X,Y,Z\n" + "1,2,3,4,0\n" * 5 + "nan,2,3,4,0\n", "row 7, u is not finite"),
    "inf": ("u,v,X,Y,Z\n" + "1,2,3,4,inf\n" * 6, "row 2, Z is not finite"),
    "text": ("u,v,X,Y,Z\n" + "1,2,3,four,0\n" * 6, "row 2, Y is not a number"),
    # Rows are the file's lines, blank ones included (the line an editor shows).
    "blank_lines": ("u,v,X,Y,Z\n\n" + "1,2,3,4,0\n" * 3 + "\n1,2,3,x,0\n", "row 7, Y is not a number"),
    "one_elevation": (
        "u,v,X,Y,Z\n"
        + "".join(
            f"{300 + 10 * math.cos(k)},{300 + 10 * math.sin(k)},{3 + math.cos(k)},{2 + math.sin(k)},1.5\n"
            for k in range(6)
        ),
        "all landmarks are at one elevation",
    ),
    "outside_image": (
        "u,v,X,Y,Z\n" + "".join(f"{100 * k},{50 * k},{3 + k},2,{k / 3}\n" for k in range(1, 8)),
        "outside the 640 x 600 image",
    ),
    # (row, column) pixels: one landmark past the bottom of the 640 x 600 frame, all inside when swapped.
    "row_column": (
        "u,v,X,Y,Z\n" + "".join(f"{300 + k},{300 + 64 * k},{3 + k},2,{k / 3}\n" for k in range(6)),
        "at pixel (305, 620) is outside the 640 x 600 image (read as (row, column) every landmark is inside it",
    ),
    # Two of one name: the report's outliers would name either (the learn page refuses them too).
    "same_name": (
        "name,u,v,X,Y,Z\n" + "".join(f"{n},{300 + k},300,{3 + k},2,0\n" for k, n in enumerate("ABCADE")),
        "rows 2 and 5 are both named 'A': give each landmark a name of its own",
    ),
    "unnamed_clash": (
        "name,u,v,X,Y,Z\n" + "".join(f"{n},{300 + k},300,{3 + k},2,0\n" for k, n in enumerate(["", "L1", "B"])),
        "rows 2 and 3 are both named 'L1' (row 2 has no name: that is the one it was given)",
    ),
}


@pytest.mark.parametrize("case", sorted(BAD_LANDMARKS))
def test_bad_landmarks_get_one_line_naming_the_file(work: Path, case: str) -> None:
    text, message = BAD_LANDMARKS[case]
    (work / "bad.csv").write_text(text)
    result = run(
        "fit",
        work / "bad.csv",
        "-o",
        work / "t.npz",
        "--camera",
        *POSITION,
        "--centre",
        320,
        300,
        "--image",
        work / "omni.png",
        "--cutoff-radius",
        0,
        "--outer-radius",
        290,
    )
    assert_one_line_error(result, "bad.csv", message)
    assert not (work / "t.npz").exists()


@pytest.mark.parametrize(
    ("args", "message", "exit_code"),
    [
        (["missing.csv", "--camera", 0, 0, 2, "--centre", 1, 1], "missing.csv: no such file", 1),
        (["lm.csv", "--camera", 0, 0, "nan", "--centre", 1, 1], "'nan' is not a finite number", 2),
        (["lm.csv", "--centre", 1, 1], "lm.csv: give --camera X0 Y0 Z0", 2),
        (["lm.csv", "--camera", 0, 0, 2], "no image centre", 2),
        (
            ["lm.csv", "--camera", *POSITION, "--centre", *CAMERA.centre, "--size", "1000000x1000000"],
            "--size 1000000x1000000: 1,000,000,000,000 entries is more than the limit",
            2,
        ),
        (["lm.csv", "--camera", *POSITION, "--centre", *CAMERA.centre, "--size", "0x10"], "M >= 4 and N >= 2", 2),
        (["lm.csv", "--camera", *POSITION, "--centre", *CAMERA.centre, "--size", "big"], "not a size like", 2),
        (["lm.csv", "--camera", *POSITION, "--image-size", "0x100"], "'--image-size': 0x100: must be positive", 2),
        (["lm.csv", "--camera", *POSITION, "--centre", 1, 1, "--pixel-sigma", 0], "'--pixel-sigma': 0 is not more", 2),
        (["lm.csv", "--camera", *POSITION, "--centre", 1, 1, "--camera-sigma", -1], "-1 is not at least 0", 2),
        (["lm.csv", "--camera", *POSITION, "--centre", 1, 1, "--cutoff-radius", -3], "-3 is not at least 0", 2),
        (
            ["lm.csv", "--camera", *POSITION, "--centre", 1, 1, "--model", "paper", "--refine-centre"],
            "the paper model takes the centre as given; --refine-centre needs another model",
            2,
        ),
        (
            ["lm.csv", "--camera", *POSITION, "--centre", *CAMERA.centre, "--image", "nope.png"],
            "nope.png: no such image file",
            1,
        ),
        # (Before, a PNG's bytes were written under any name.)
        (["lm.csv", "--camera", *POSITION, "--centre", 1, 1, "--plot", "p.jpg"], "the fit plot is written as PNG", 2),
    ],
)
def test_bad_fit_arguments(work: Path, args: list[object], message: str, exit_code: int) -> None:
    resolved = [work / a if isinstance(a, str) and a.endswith((".csv", ".png")) else a for a in args]
    result = run("fit", *resolved, "-o", work / "t.npz")
    # 2 for usage (an option missing, unparsable or out of range; options that do not go together),
    # 1 for input the command refuses (a file missing or wrong).
    assert_one_line_error(result, message, exit_code=exit_code)
    assert not (work / "t.npz").exists()


def test_a_table_is_written_as_npz(work: Path) -> None:
    """``fit -o t.png`` wrote a table (an .npz archive) under that name."""
    for name in ("t.png", "t"):
        result = run("fit", work / "lm.csv", "-o", work / name, "--camera", *POSITION, "--centre", *CAMERA.centre)
        assert_one_line_error(result, "a table is written as .npz (name it so)", exit_code=2)
        assert not (work / name).exists()


@pytest.mark.parametrize(
    ("options", "message", "exit_code"),
    [
        # Every one a usage error (exit 2): the options' values, whatever the table.
        (["--size", "1000000x1000000"], "too large", 2),
        (["--size", "0x100"], "Invalid value for '--size': 0x100: width and height must be positive", 2),
        (["--size", "-5x100"], "must be positive", 2),
        (["--size", "big"], "is not a size like 1024x512", 2),  # click cannot parse it
        (["--band", 1, -1], "z_bottom < z_top", 2),
        (["--distance", -2], "distance must be positive", 2),
        (["--plane-width", 5], "needs width < 2 D", 2),
        # Exactly 2 D: the plane passes through the camera (issue 14: it wrote a meaningless image, exit 0).
        (["--plane-width", 4], "needs width < 2 D", 2),
    ],
)
def test_bad_view_parameters(work: Path, options: list[object], message: str, exit_code: int) -> None:
    table_path = fit_table(work)
    base = {"--distance": [2], "--plane-width": [2], "--band": [-2, 0.3], "--azimuth-deg": [10], "--size": ["100x80"]}
    for flag in options:
        if isinstance(flag, str) and flag in base:
            base.pop(flag)
    args = [a for flag, values in base.items() for a in (flag, *values)]
    result = run("plane", table_path, work / "omni.png", "-o", work / "out.png", *args, *options)
    assert_one_line_error(result, message, exit_code=exit_code)
    assert not (work / "out.png").exists()


def test_bad_view_inputs(work: Path) -> None:
    table_path = fit_table(work)
    (work / "broken.png").write_bytes(b"not an image")
    (work / "corrupt.npz").write_bytes(table_path.read_bytes()[:5000])
    small = work / "small.png"
    cv2.imwrite(str(small), np.zeros((10, 10), np.uint8))
    cases = [
        ([table_path, work / "nothere.png"], "nothere.png: no such image file"),
        ([table_path, work / "broken.png"], "broken.png: cannot read it as an image"),
        ([work / "corrupt.npz", work / "omni.png"], "corrupt.npz: not a readable panomap table"),
        ([work / "none.npz", work / "omni.png"], "none.npz: no such table file"),
        ([table_path, small], "small.png: the image is 10 x 10"),
    ]
    for inputs, message in cases:
        result = run("panorama", *inputs, "-o", work / "out.png", "--size", "100x20")
        assert_one_line_error(result, message)
        assert not (work / "out.png").exists()


def test_sixteen_bit_output_into_jpeg_is_refused_before_writing(work: Path) -> None:
    table_path = fit_table(work)
    cv2.imwrite(str(work / "deep.png"), np.zeros((SIZE[1], SIZE[0]), np.uint16) + 3000)
    result = run("panorama", table_path, work / "deep.png", "-o", work / "out.jpg", "--size", "100x20")
    assert_one_line_error(result, "16-bit images need PNG")
    assert not (work / "out.jpg").exists()


def test_a_real_process_prints_no_traceback(work: Path) -> None:
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "panomap",
            "panorama",
            str(work / "no.npz"),
            str(work / "omni.png"),
            "-o",
            str(work / "o.png"),
        ],
        capture_output=True,
        text=True,
        check=False,
    )
    assert result.returncode == 1
    assert result.stderr.strip().splitlines() == [f"panomap: error: {work / 'no.npz'}: no such table file"]


def test_the_package_loads_its_names_on_first_use() -> None:
    """``import panomap`` loads no NumPy (the command line and small scripts start faster); names still resolve."""
    code = (
        "import sys, panomap; assert 'numpy' not in sys.modules, 'numpy loaded'; "
        "from panomap.views import GenericPanorama; assert panomap.GenericPanorama is GenericPanorama; "
        "assert set(panomap.__all__) <= set(dir(panomap)); "
        "assert all(getattr(panomap, name) is not None for name in panomap.__all__)"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
    import panomap

    with pytest.raises(AttributeError, match="no attribute 'nothing'"):
        panomap.nothing  # noqa: B018


def test_bare_panomap_prints_its_help_laid_out() -> None:
    """Issue 14: a bare `panomap` printed its whole help flattened into one error line."""
    result = subprocess.run([sys.executable, "-m", "panomap"], capture_output=True, text=True, check=False)
    assert result.returncode == 0 and result.stderr == ""
    lines = result.stdout.splitlines()
    assert lines[0] == "Usage: python -m panomap [OPTIONS] COMMAND [ARGS]..."
    assert any(line.strip().startswith("fit ") for line in lines) and len(lines) > 20


def test_long_landmark_names_are_printed_whole_and_one_ray_is_singular(work: Path) -> None:
    """Issue 14: names were cut to 12 characters in the fit report and info; "1 rays reach"."""
    text = (work / "lm.csv").read_text().splitlines()
    header, rows = text[0], text[1:]
    assert header == "name,u,v,X,Y,Z"
    named = [f"corner_of_the_north_wall_{k}," + row.split(",", 1)[1] for k, row in enumerate(rows)]
    (work / "lm.csv").write_text("\n".join([header, *named]) + "\n")
    table_path = fit_table(work)
    for output in (run("info", table_path).output,):
        for k in range(len(rows)):
            assert f"corner_of_the_north_wall_{k} " in output
    (work / "px.csv").write_text(f"u,v\n{CAMERA.centre[0] + 150.0},{CAMERA.centre[1]}\n")
    result = run("unproject", table_path, work / "px.csv", "-o", work / "rays.csv", "--z", 0)
    assert result.exit_code == 0, result.stderr
    assert "1 ray reaches the plane Z = 0" in result.output


@pytest.mark.slow
def test_a_huge_number_is_refused_in_one_line_without_a_numpy_warning(work: Path) -> None:
    """1e300 is finite, but no camera, room or pixel is that large: refused with its place named (issue 14:
    ``fit --camera 1e300 ...`` printed NumPy's overflow RuntimeWarning, ``floor --x 0 1e300`` too)."""
    table_path = fit_table(work)
    (work / "far.csv").write_text((work / "lm.csv").read_text() + "far,1,2,1e300,0,0\n")
    (work / "points.csv").write_text("X,Y,Z\n1,2,0\n1e300,0,0\n")
    usage = "'1e300' is too large (at most 1e+09 in size)"
    cases = [
        (
            ["fit", work / "lm.csv", "-o", work / "t.npz", "--camera", "1e300", 0, 2, "--image", work / "omni.png"],
            2,
            usage,
        ),
        (
            ["floor", table_path, work / "omni.png", "-o", work / "t.png", "--z", 0, "--x", 0, "1e300", "--y", 0, 1],
            2,
            usage,
        ),
        (
            ["fit", work / "far.csv", "-o", work / "t.npz", "--camera", *POSITION, "--image", work / "omni.png"],
            1,
            "X is too large",
        ),
        (["project", table_path, work / "points.csv", "-o", work / "t.csv"], 1, "row 3, X is too large: '1e300'"),
        (
            [
                "video",
                table_path,
                work / "none.mp4",
                "-o",
                work / "t.mp4",
                "--view",
                "cylinder:distance=1e300,band=-1:0,size=64x32",
            ],
            2,  # (a --view SPEC is the command line's: usage, checked before the input)
            "distance='1e300' is too large",
        ),
    ]
    for args, code, message in cases:
        result = subprocess.run(
            [sys.executable, "-m", "panomap", *(str(a) for a in args)], capture_output=True, text=True, check=False
        )
        assert result.returncode == code, result.stderr
        lines = result.stderr.strip().splitlines()
        assert len(lines) == 1 and message in lines[0], result.stderr
        assert "Warning" not in result.stderr
    assert not any(work.glob("t.*"))


@pytest.mark.slow
def test_a_broken_image_gets_our_one_line_and_nothing_from_libpng_or_opencv(tmp_path: Path) -> None:
    """In a real process (libpng and OpenCV write to the stderr file descriptor, not through Python)."""
    cv2.imwrite(str(tmp_path / "good.png"), (np.random.default_rng(1).random((200, 300, 3)) * 255).astype(np.uint8))
    data = (tmp_path / "good.png").read_bytes()
    (tmp_path / "half.png").write_bytes(data[: len(data) // 2])  # libpng: "libpng error: ... incomplete"
    (tmp_path / "head.png").write_bytes(data[:100])  # OpenCV: "[ WARN:0@...] ... PNG input buffer is incomplete"
    # A Radiance header declaring 40000 x 40000 (Pillow cannot read it; OpenCV raised cv2.error, a traceback).
    (tmp_path / "huge.hdr").write_bytes(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 40000 +X 40000\nxxxx")
    (tmp_path / "short.hdr").write_bytes(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 4000 +X 4000\nxxxx")  # [ERROR]
    for name, message in (
        ("half.png", "a truncated or corrupt PNG"),
        ("head.png", "a truncated or corrupt PNG"),
        # (Radiance images are refused from their first bytes now: 32-bit float, never decoded.)
        ("huge.hdr", "this one is a Radiance HDR image (32-bit float)"),
        ("short.hdr", "this one is a Radiance HDR image (32-bit float)"),
    ):
        result = subprocess.run(
            [sys.executable, "-m", "panomap", "centre", str(tmp_path / name)],
            capture_output=True,
            text=True,
            check=False,
        )
        assert result.returncode == 1
        lines = result.stderr.splitlines()
        assert len(lines) == 1, result.stderr
        assert lines[0].startswith(f"panomap: error: {tmp_path / name}: ") and message in lines[0], lines


@pytest.mark.slow
def test_a_truncated_jpeg_is_said_so_and_never_taken_for_a_video(work: Path, tmp_path: Path) -> None:
    """A JPEG cut short decoded half grey (or PyAV read it as a one-frame video): `panorama` advised
    `panomap video`, and `centre` / `fit --image` went on with the half image, exit 0."""
    image = cv2.imread(str(work / "omni.png"))
    ok, encoded = cv2.imencode(".jpg", image)
    assert ok
    data = encoded.tobytes()
    (tmp_path / "whole.jpg").write_bytes(data)
    (tmp_path / "half.jpg").write_bytes(data[: len(data) // 2])
    (tmp_path / "head.jpg").write_bytes(data[:300])  # the headers only, no image data
    table = fit_table(work)
    for name in ("half.jpg", "head.jpg"):
        for args in (["centre", tmp_path / name], ["panorama", table, tmp_path / name, "-o", tmp_path / "p.png"]):
            result = subprocess.run(
                [sys.executable, "-m", "panomap", *(str(a) for a in args)], capture_output=True, text=True, check=False
            )
            assert result.returncode == 1, result.stderr
            lines = result.stderr.splitlines()
            assert len(lines) == 1 and lines[0].startswith(f"panomap: error: {tmp_path / name}: "), result.stderr
            assert "a truncated or corrupt JPEG" in lines[0] and "video" not in lines[0], lines
    assert not (tmp_path / "p.png").exists()
    whole = run("panorama", table, tmp_path / "whole.jpg", "-o", tmp_path / "p.png")
    assert whole.exit_code == 0, whole.output + whole.stderr


@pytest.mark.parametrize("spread", ["one pixel", "one radius"])
def test_landmarks_that_cannot_be_fitted_get_one_line_and_no_scipy_warning(work: Path, spread: str) -> None:
    """SciPy's ConstantInputWarning (two lines naming our source file) was printed before the error."""
    lines = (work / "lm.csv").read_text().splitlines()
    rows = [line.split(",") for line in lines[1:]]
    for k, row in enumerate(rows):  # every pixel at (300, 250), or all on one circle about the centre
        angle = 2 * math.pi * k / len(rows)
        row[1:3] = ("300", "250") if spread == "one pixel" else (f"{321.4 + 50 * math.cos(angle):.3f}",
                                                                  f"{298.2 + 50 * math.sin(angle):.3f}")  # fmt: skip
    (work / "bad.csv").write_text("\n".join([lines[0], *(",".join(row) for row in rows)]) + "\n")
    args = ["fit", work / "bad.csv", "-o", work / "bad.npz", "--camera", *POSITION, "--centre", *CAMERA.centre]
    result = subprocess.run(
        [sys.executable, "-m", "panomap", *(str(a) for a in args)], capture_output=True, text=True, check=False
    )
    assert result.returncode == 1, result.stderr
    assert len(result.stderr.splitlines()) == 1, result.stderr
    expected = "all 12 landmarks are at one pixel (300, 250)" if spread == "one pixel" else "looks down or up"
    assert expected in result.stderr and "Warning" not in result.stderr
    assert not (work / "bad.npz").exists()


def test_every_command_takes_the_one_quiet_option(work: Path) -> None:
    """Issue 53: -q was an option of 7 commands of 17 (`unproject -q` failed); it is declared once, on each."""
    from panomap.cli.app import COMMANDS

    helps = {command.name: [param for param in command.params if "-q" in param.opts] for command in COMMANDS}
    assert all(len(found) == 1 and found[0].opts == ["-q", "--quiet"] for found in helps.values()), helps
    table_path = fit_table(work)
    quiet = run("fit", work / "lm.csv", "-o", work / "q.npz", "--camera", *POSITION, "--image", work / "omni.png", "-q")
    assert quiet.exit_code == 0 and quiet.stdout == "", quiet.output + quiet.stderr
    (work / "px.csv").write_text(f"u,v\n{CAMERA.centre[0] + 150.0},{CAMERA.centre[1]}\n")
    said = run("unproject", table_path, work / "px.csv", "-o", work / "rays.csv", "--z", 0)
    result = run("unproject", "-q", table_path, work / "px.csv", "-o", work / "rays2.csv", "--z", 0)
    assert said.stdout.startswith("wrote ") and result.exit_code == 0 and result.stdout == "", result.stderr
    assert (work / "rays2.csv").read_text() == (work / "rays.csv").read_text()
    shown = run("info", table_path, "-q")  # the result asked for is printed all the same
    assert shown.exit_code == 0 and "radial model" in shown.stdout


def test_a_picture_given_as_landmarks_points_to_image_and_a_glob_that_matches_none_is_refused(work: Path) -> None:
    """Issue 53: ``fit room.jpg -o cam.npz`` read the picture as landmarks; it gets one line pointing to --image."""
    result = run("fit", work / "omni.png", "-o", work / "cam.npz")
    assert_one_line_error(result, "is a picture, not landmarks", f"--image {work / 'omni.png'}", exit_code=2)
    result = run("fit", "-o", work / "cam.npz", "--image", work / "omni.png", work / "omni.png")
    assert_one_line_error(result, "is a picture, not landmarks", exit_code=2)
    result = run("fit", "-o", work / "cam.npz", "--image", str(work / "*.jpg"))
    assert_one_line_error(result, "'--image'", "matches no image", exit_code=2)
    (work / "empty").mkdir()
    result = run("fit", "-o", work / "cam.npz", "--image", work / "empty")
    assert_one_line_error(result, "'--image'", "the folder holds no image", exit_code=2)


def test_the_help_names_every_calibration_format_and_the_equirect_view() -> None:
    """``panomap --help``, where a new user starts, names every format ``import`` reads (it named four of eight)
    and the whole-sphere view beside the others."""
    from panomap.interop.readers import READERS

    tools = {"ocam": "OCamCalib", "gyroflow": "gyroflow", "opencv": "OpenCV", "kalibr": "Kalibr"}
    tools |= {"colmap": "COLMAP", "boofcv": "BoofCV", "basalt": "Basalt", "hugin": "Hugin", "opencalib": "OpenCalib"}
    text = " ".join(run("--help").output.split())
    assert set(READERS) == set(tools)
    assert all(tool in text for tool in tools.values()), text
    assert "panomap equirect cam.npz omni.png" in text


@pytest.mark.parametrize(
    ("option", "what"), [("--overlay", "the overlay"), ("--uncertainty-plot", "the figure"), ("-o", "a table")]
)
def test_fit_from_pictures_refuses_outputs_named_for_another_format_before_any_work(
    tmp_path: Path, option: str, what: str
) -> None:
    """``fit --image``'s table, overlay and figure go through the one check the table commands share
    (``check_table_outputs``): a name for another format is refused in one line, nothing written."""
    picture = tmp_path / "in" / "boards.png"
    picture.parent.mkdir()
    cv2.imwrite(str(picture), np.zeros((48, 64), np.uint8))
    out = tmp_path / "out"
    out.mkdir()
    names = {"-o": out / "t.npz", "--overlay": out / "o.png", "--uncertainty-plot": out / "u.png"}
    names[option] = out / ("t.png" if option == "-o" else "x.jpg")
    args = [arg for name, path in names.items() for arg in (name, path)]
    result = run("fit", "--image", picture, *args)
    written = ".npz (name it so)" if option == "-o" else "PNG (name it .png)"
    assert_one_line_error(result, f"'{option}'", f"{what} is written as {written}", exit_code=2)
    assert list(out.iterdir()) == []
