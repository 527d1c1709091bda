"""Issue 44 (hardening 4): the new doors (import, export, learning from pictures) held to the old promises.

Every command that writes runs one output check (:func:`panomap.files.check_outputs`): an output is never
one of the run's inputs (by device and inode: the same name, another spelling, a symbolic or a hard link),
and it is a new name or a regular file (never a FIFO, a device node or a folder). A table is checked at
writing as every reader will check it; inputs that only cost time (an OCam polynomial of 20001
coefficients, the same picture given many times, a camchain with 100 MB of comments) are refused or read
once; options a command would not use are refused, naming them.
"""

from __future__ import annotations

import dataclasses
import os
import re
import stat
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
import yaml

from panomap.errors import PanomapError
from panomap.simulate import standard_cameras
from panomap.table.file import MAX_IMAGE_SIDE, load_table, save_table

from helpers import assert_one_line_error, learn_table, run, spread_landmarks

OCAM = """#polynomial coefficients for the DIRECT mapping function
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
WIDTH, HEIGHT = 748, 480


@pytest.fixture(scope="module")
def inputs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder with an OCam calibration (calib.txt), its table (cam.npz), an image of its size (omni.png)
    and a landmark file (lm.csv)."""
    folder = tmp_path_factory.mktemp("hardening")
    (folder / "calib.txt").write_text(OCAM)
    result = run("import", folder / "calib.txt", "-o", folder / "cam.npz")
    assert result.exit_code == 0, result.output + result.stderr
    v, u = np.mgrid[0:HEIGHT, 0:WIDTH]
    cv2.imwrite(str(folder / "omni.png"), np.stack([u % 256, v % 256, (u + v) % 256], -1).astype(np.uint8))
    (folder / "lm.csv").write_text("u,v,X,Y,Z\n100,200,1,2,0\n")
    return folder


def copy_in(inputs: Path, folder: Path, *names: str) -> dict[str, Path]:
    """Fresh copies of ``names`` from the fixture's folder in ``folder``."""
    copies = {}
    for name in names:
        copies[name] = folder / name
        copies[name].write_bytes((inputs / name).read_bytes())
    return copies


def spelled(path: Path, how: str) -> Path:
    """Another way to reach ``path``: itself, a symbolic link, a hard link, or another spelling of its name."""
    if how == "same":
        return path
    if how == "spelling":
        (path.parent / "sub").mkdir(exist_ok=True)
        return path.parent / "sub" / ".." / "." / path.name
    other = path.parent / f"other{path.suffix}"
    if how == "symlink":
        other.symlink_to(path)
    else:
        os.link(path, other)
    return other


# ----------------------------------------------------------------------------- inputs never overwritten


WAYS = ["same", "symlink", "hardlink", "spelling"]


@pytest.mark.parametrize("how", WAYS)
def test_import_refuses_to_write_over_its_calibration(inputs: Path, tmp_path: Path, how: str) -> None:
    calibration = copy_in(inputs, tmp_path, "calib.txt")["calib.txt"]
    result = run("import", calibration, "-o", spelled(calibration, how))
    assert_one_line_error(result, "the calibration", "refusing to overwrite an input", exit_code=1)
    assert calibration.read_text() == OCAM


@pytest.mark.parametrize("how", WAYS)
def test_import_refuses_to_write_over_its_image(inputs: Path, tmp_path: Path, how: str) -> None:
    files = copy_in(inputs, tmp_path, "calib.txt", "omni.png")
    before = files["omni.png"].read_bytes()
    result = run("import", files["calib.txt"], "-o", spelled(files["omni.png"], how), "--image", files["omni.png"])
    assert_one_line_error(result, "the image", "refusing to overwrite an input", exit_code=1)
    assert files["omni.png"].read_bytes() == before


@pytest.mark.parametrize("how", WAYS)
def test_export_refuses_to_write_over_its_table(inputs: Path, tmp_path: Path, how: str) -> None:
    table = copy_in(inputs, tmp_path, "cam.npz")["cam.npz"]
    before = table.read_bytes()
    result = run("export", table, "-o", spelled(table, how), "--format", "ocam")
    assert_one_line_error(result, "the table", "refusing to overwrite an input", exit_code=1)
    assert table.read_bytes() == before


def special(tmp_path: Path, kind: str, suffix: str) -> tuple[Path, int]:
    """An output name that is not a regular file: a FIFO or a link to a device node (/dev/null: never the
    node itself, which a failing test would replace); with its mode, to check it is still what it was. (A
    folder is refused by click, exit 2.)"""
    path = tmp_path / f"out{suffix}"
    if kind == "fifo":
        os.mkfifo(path)
    else:
        path.symlink_to("/dev/null")
    return path, os.lstat(path).st_mode


def commands(inputs: Path, output: Path) -> dict[str, list[object]]:
    """Every command that writes, with ``output`` as its output (each refused before any work)."""
    calib, table, omni, landmarks = (inputs / n for n in ("calib.txt", "cam.npz", "omni.png", "lm.csv"))
    return {
        "import": ["import", calib, "-o", output],
        "export": ["export", table, "-o", output, "--format", "ocam"],
        "fit": ["fit", landmarks, "-o", output, "--camera", 0, 0, 1, "--centre", 374, 240],
        "fit-lines": ["fit", "-o", output, "--image", omni],
        "fit-overlay": ["fit", "-o", output.parent / "t.npz", "--image", omni, "--overlay", output],
        "panorama": ["panorama", table, omni, "-o", output, "--size", "64x16"],
        "save-map": ["panorama", table, omni, "-o", output.parent / "p.png", "--size", "64x16", "--save-map", output],
        "project": ["project", table, landmarks, "-o", output],
        "centre": ["centre", omni, "--overlay", output],
        "video": ["video", table, omni, "-o", output, "--view", "panorama:size=64x16"],
    }


SUFFIX = {"import": ".npz", "export": ".txt", "fit": ".npz", "fit-lines": ".npz", "save-map": ".npy", "project": ".csv"}


@pytest.mark.parametrize("kind", ["fifo", "device"])
@pytest.mark.parametrize(
    "command",
    ["import", "export", "fit", "fit-lines", "fit-overlay", "panorama", "save-map", "project", "centre", "video"],
)
def test_an_output_that_is_not_a_regular_file_is_refused(inputs: Path, tmp_path: Path, command: str, kind: str) -> None:
    output, mode = special(tmp_path, kind, SUFFIX.get(command, ".mp4" if command == "video" else ".png"))
    started = time.monotonic()
    result = run(*commands(inputs, output)[command])
    words = {"fifo": "a FIFO", "device": "a character device"}[kind]
    assert_one_line_error(result, str(output), words, exit_code=1)
    assert os.lstat(output).st_mode == mode  # still the FIFO, the link to the device
    assert time.monotonic() - started < 3  # refused before any work
    assert sorted(p.name for p in tmp_path.iterdir()) == [output.name]


def test_the_demo_checks_all_its_outputs_before_any_work(tmp_path: Path) -> None:
    (tmp_path / "out").mkdir()
    fifo = tmp_path / "out" / "fit.png"
    os.mkfifo(fifo)
    started = time.monotonic()
    result = run("demo", "-o", tmp_path / "out")
    assert_one_line_error(result, str(fifo), "a FIFO", exit_code=1)
    assert time.monotonic() - started < 3
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)
    assert [p.name for p in (tmp_path / "out").iterdir()] == ["fit.png"]


def test_batch_refuses_an_output_that_is_its_table(inputs: Path, tmp_path: Path) -> None:
    files = copy_in(inputs, tmp_path, "omni.png")
    table = tmp_path / "t.png"  # a table file may have any name; a still image's output keeps its suffix
    table.write_bytes((inputs / "cam.npz").read_bytes())
    before = table.read_bytes()
    result = run("batch", files["omni.png"], "--table", table, "-o", str(table), "--view", "panorama:size=64x16",
                 "--record", tmp_path / "record.jsonl")  # fmt: skip
    assert_one_line_error(result, str(table), "refusing to overwrite", exit_code=1)
    assert table.read_bytes() == before


# ----------------------------------------------------------------------------- a table every reader can load


def test_a_calibration_for_an_impossible_image_is_refused_at_import(tmp_path: Path) -> None:
    path = tmp_path / "calib.txt"
    path.write_text(OCAM.replace("480 748\n", "1000000000 1000000000\n"))
    out = tmp_path / "cam.npz"
    result = run("import", path, "-o", out)
    assert_one_line_error(result, str(path), "image size", f"at most {MAX_IMAGE_SIDE} px a side", exit_code=1)
    assert not out.exists()


def test_a_table_no_command_could_load_is_not_written(inputs: Path, tmp_path: Path) -> None:
    # The class of the fault: whatever makes the table, save_table holds it to load_table's checks.
    table = dataclasses.replace(load_table(inputs / "cam.npz"), image_size=(MAX_IMAGE_SIDE + 1, HEIGHT))
    out = tmp_path / "cam.npz"
    with pytest.raises(PanomapError, match=r"no command could load this table .*image_size"):
        save_table(table, out)
    assert list(tmp_path.iterdir()) == []
    save_table(load_table(inputs / "cam.npz"), out)  # a good table is written, and loads
    assert load_table(out).size == load_table(inputs / "cam.npz").size


# ----------------------------------------------------------------------------- export: the figure it prints


def table_and_rays(kind: str) -> tuple[Any, np.ndarray, np.ndarray]:
    """A table fitted to 40 landmarks of a simulated 800 x 800 camera of ``kind``; its pixels on a grid
    running to both ends of its elevation range (the outermost ring included), and their rays in the
    exported (OpenCV) frame: z the optical axis, alpha = rho + pi/2 from it looking down, at image angle
    phi = s theta + phi0."""
    camera = standard_cameras((800, 800), centre=(401.3, 396.2), s=-1, phi0=0.4)[kind]
    position = (0.3, -0.2, 2.5)
    table, _ = learn_table(camera, position, spread_landmarks(camera, position, 40, np.random.default_rng(3)),
                           (800, 800))  # fmt: skip
    theta, rho = np.meshgrid(
        np.linspace(0, 2 * np.pi, 360, endpoint=False), np.linspace(*table.elevation_range, 121), indexing="ij"
    )
    uv = table.sample(theta, rho).astype(np.float64).reshape(-1, 2)
    alpha, phi = (rho + np.pi / 2).ravel(), (table.model.s * theta + table.model.phi0).ravel()
    ray = np.stack([np.sin(alpha) * np.cos(phi), np.sin(alpha) * np.sin(phi), np.cos(alpha)], -1)
    good = np.all(np.isfinite(uv), axis=1) & (np.sin(alpha) > 1e-9)
    return table, uv[good], ray[good]


def printed_error(output: str) -> float:
    return float(re.search(r"over its valid range: ([0-9.]+) px", output).group(1))


def test_export_prints_its_largest_error_over_the_whole_range_outer_ring_included(tmp_path: Path) -> None:
    # The check grid stopped short of both ends: 0.186 px printed, 0.290 px at the outermost ring.
    table, uv, ray = table_and_rays("hyperbolic")
    save_table(table, tmp_path / "cam.npz")
    out = tmp_path / "calib_results.txt"
    result = run("export", tmp_path / "cam.npz", "-o", out, "--format", "ocam")
    assert result.exit_code == 0, result.output + result.stderr
    rows = [line.split() for line in out.read_text().splitlines() if line.strip() and not line.startswith("#")]
    invpol, (xc, yc), (c, d, e) = [float(x) for x in rows[1][1:]], map(float, rows[2]), map(float, rows[3])
    # OCamCalib's world2cam (ocam_functions.c), its frame (y, x, -z) of the OpenCV one.
    x, y, z = ray[:, 1], ray[:, 0], -ray[:, 2]
    norm = np.hypot(x, y)
    rho = sum(p * np.arctan(z / norm) ** k for k, p in enumerate(invpol))
    xp, yp = x / norm * rho, y / norm * rho
    error = np.hypot(e * xp + yp + yc - uv[:, 0], xp * c + yp * d + xc - uv[:, 1])
    assert error.max() <= printed_error(result.output) + 1e-3


def test_a_double_sphere_export_is_fitted_from_several_starts(tmp_path: Path) -> None:
    # From (xi, alpha) = (0, 0.5) alone, the fit of this equisolid fisheye stopped at 0.84 px.
    table, uv, ray = table_and_rays("equisolid")
    save_table(table, tmp_path / "cam.npz")
    out = tmp_path / "camchain.yaml"
    result = run("export", tmp_path / "cam.npz", "-o", out, "--format", "kalibr-ds")
    assert result.exit_code == 0, result.output + result.stderr
    xi, alpha, fx, fy, cx, cy = yaml.safe_load(out.read_text())["cam0"]["intrinsics"]
    # The double sphere's projection (Usenko et al. 2018), written here.
    d1 = np.linalg.norm(ray, axis=1)
    d2 = np.sqrt(ray[:, 0] ** 2 + ray[:, 1] ** 2 + (xi * d1 + ray[:, 2]) ** 2)
    m = alpha * d2 + (1 - alpha) * (xi * d1 + ray[:, 2])
    error = np.hypot(fx * ray[:, 0] / m + cx - uv[:, 0], fy * ray[:, 1] / m + cy - uv[:, 1])
    assert error.max() < 0.05
    assert error.max() <= printed_error(result.output) + 1e-3


# ----------------------------------------------------------------------------- small inputs, small costs


def test_an_ocam_polynomial_of_thousands_of_coefficients_is_refused_at_once(tmp_path: Path) -> None:
    # 20001 coefficients took 89 s to import (every evaluation costs the degree).
    path = tmp_path / "calib.txt"
    pol = " ".join(["-2.063866e+02", "0", "2.165610e-03"] + ["0"] * 1998)
    path.write_text(OCAM.replace("5 -2.063866e+02 0.000000e+00 2.165610e-03 -4.495456e-06 1.810639e-08", f"2001 {pol}"))
    out = tmp_path / "cam.npz"
    started = time.monotonic()
    result = run("import", path, "-o", out)
    assert_one_line_error(result, str(path), "pol has 2001 coefficients; at most 64", exit_code=1)
    assert time.monotonic() - started < 2
    assert not out.exists()


def test_a_camchain_is_parsed_once(inputs: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # Detection parsed the YAML, then the reader again, and `import --image` read the file twice over: a
    # camchain followed by 100 MB of comments cost minutes.
    path = tmp_path / "camchain.yaml"
    path.write_text(
        "cam0:\n  camera_model: ds\n  intrinsics: [-0.2, 0.58, 200.0, 199.0, 373.5, 239.5]\n"
        "  distortion_model: none\n  distortion_coeffs: []\n  resolution: [748, 480]\n" + "# a comment\n" * 1000
    )
    parses = []
    for name in ("load", "safe_load"):
        real = getattr(yaml, name)
        monkeypatch.setattr(yaml, name, lambda *a, real=real, **k: parses.append(1) or real(*a, **k))
    result = run("import", path, "-o", tmp_path / "cam.npz", "--image", inputs / "omni.png")
    assert result.exit_code == 0, result.output + result.stderr
    assert len(parses) == 1


def test_a_camchain_followed_by_megabytes_of_comments_is_refused_at_once(tmp_path: Path) -> None:
    # Four pure-Python parses of 100 MB of comments took minutes; a calibration file is a few kilobytes.
    path = tmp_path / "camchain.yaml"
    path.write_text(
        "cam0:\n  camera_model: ds\n  intrinsics: [-0.2, 0.58, 200.0, 199.0, 373.5, 239.5]\n"
        "  distortion_model: none\n  distortion_coeffs: []\n  resolution: [748, 480]\n"
        + ("# " + "x" * 78 + "\n")
        * 125_000  # 10 MB
    )
    started = time.monotonic()
    result = run("import", path, "-o", tmp_path / "cam.npz", "--table-size", "360x90")
    assert_one_line_error(result, f"{path}: ", "more than a calibration file holds", exit_code=1)
    assert time.monotonic() - started < 2.5
    assert not (tmp_path / "cam.npz").exists()


@pytest.mark.parametrize("how", ["same", "symlink", "copy"])
def test_one_picture_given_twice_to_learn_from_is_refused(inputs: Path, tmp_path: Path, how: str) -> None:
    # The same picture given 50 times was learned from 50 times (47 s): its lines add nothing.
    image = copy_in(inputs, tmp_path, "omni.png")["omni.png"]
    again = image if how == "same" else tmp_path / "again.png"
    if how == "symlink":
        again.symlink_to(image)
    elif how == "copy":
        again.write_bytes(image.read_bytes())
    result = run("fit", "-o", tmp_path / "cam.npz", *["--image", image] * 2, "--image", again)
    assert_one_line_error(result, "'--image'", "one picture", "give each picture once", exit_code=2)
    assert not (tmp_path / "cam.npz").exists()


# ----------------------------------------------------------------------------- no option silently ignored


@pytest.mark.parametrize(
    ("options", "named"),
    [
        (["--centre", 374, 240], "--centre"),
        (["--cutoff-radius", 30], "--cutoff-radius"),
        (["--outer-radius", 200], "--outer-radius"),
        (["--camera", 0, 0, 1], "--camera"),
        (["--tilt", "none"], "--tilt"),
        (["--tilt", "fit"], "--tilt"),  # (its default, given: still a landmark fit's option)
        (["--image-size", "748x480"], "--image-size"),
        (["--size", "360x90"], "--size"),
        (["--no-refine-centre"], "--refine-centre/--no-refine-centre"),
        (["--keep-outliers", "--pixel-sigma", 2], "--pixel-sigma, --keep-outliers"),
        (["--viewpoint", "caustic"], "--viewpoint"),
    ],
)
def test_learning_from_pictures_refuses_the_options_it_would_ignore(
    inputs: Path, tmp_path: Path, options: list[object], named: str
) -> None:
    started = time.monotonic()
    result = run("fit", "-o", tmp_path / "cam.npz", "--image", inputs / "omni.png", *options)
    assert_one_line_error(result, named, "for a fit to LANDMARKS", "does not use", exit_code=2)
    assert time.monotonic() - started < 2  # before any work
    assert not (tmp_path / "cam.npz").exists()
