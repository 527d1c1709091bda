"""Maps for ffmpeg's remap filter: 16-bit PGM planes, and ffmpeg itself applying them.

ffmpeg's ``remap`` takes two grey 16-bit streams, xmap and ymap, holding each output
pixel's integer source column and row; a position outside the frame gives the fill
colour (black). It comes from the ``imageio-ffmpeg`` package (a static build), listed in
the ``test`` extras.
"""

from __future__ import annotations

import math
import subprocess
from pathlib import Path

import cv2
import imageio_ffmpeg
import numpy as np
import pytest
from click.testing import CliRunner

from panomap.camera.model import CameraModel
from panomap.camera.radial import RadialFunction
from panomap.cli.app import main
from panomap.errors import PanomapError
from panomap.io.images import map_to_pgm, save_map_pgm
from panomap.remap import Remapper
from panomap.simulate.cameras import RadialCamera
from panomap.table.file import save_table
from panomap.table.table import PanoMappingTable, fill_entries

from helpers import assert_map_sees_like_the_camera, perspective_directions

IMAGE_SIZE = (320, 300)


def test_map_planes_round_half_to_even_and_mark_no_source() -> None:
    map_uv = np.array(
        [[[0.4, 1.6], [2.5, 3.5], [np.nan, 4.0]], [[-0.4, -0.2], [-0.6, 2.0], [np.inf, 1.0]]], dtype=np.float32
    )
    xmap, ymap = map_to_pgm(map_uv)
    assert xmap.dtype == np.uint16 and xmap.shape == (2, 3)
    # rint, as cv2.remap's nearest neighbour: 2.5 -> 2, 3.5 -> 4, -0.4 -> 0; -0.6 rounds to -1,
    # outside any frame, and NaN or inf is no source: 65535.
    np.testing.assert_array_equal(xmap, [[0, 2, 65535], [0, 65535, 65535]])
    np.testing.assert_array_equal(ymap, [[2, 4, 65535], [0, 65535, 65535]])
    with pytest.raises(PanomapError, match="beyond pixel 65534"):
        map_to_pgm(np.array([[[70000.0, 1.0]]], dtype=np.float32))


def test_pgm_files_are_16_bit_big_endian_p5(tmp_path: Path) -> None:
    map_uv = np.stack(np.meshgrid(np.arange(5.0) * 300, np.arange(3.0)), axis=-1).astype(np.float32)
    x_path, y_path = save_map_pgm(tmp_path / "m", map_uv)
    assert (x_path.name, y_path.name) == ("m_x.pgm", "m_y.pgm")
    data = x_path.read_bytes()
    header = b"P5\n5 3\n65535\n"
    assert data.startswith(header)
    # Big-endian 16-bit samples, row by row: 0, 300, 600, 900, 1200.
    np.testing.assert_array_equal(np.frombuffer(data[len(header) :], ">u2")[:5], [0, 300, 600, 900, 1200])
    np.testing.assert_array_equal(cv2.imread(str(y_path), cv2.IMREAD_UNCHANGED), map_uv[..., 1])


def fisheye_table() -> PanoMappingTable:
    """An equidistant fisheye looking down, r = 95 alpha, centred in a 320 x 300 image."""
    model = CameraModel((159.5, 149.5), RadialFunction("odd1", (95.0,), "down"), -1, 0.4)
    elevations = (-math.pi / 2, 0.0)
    return PanoMappingTable(
        fill_entries(model, (1024, 160), elevations), elevations, model, (0.0, 0.0, 2.0), IMAGE_SIZE, 0.0, 149.5
    )


def test_ffmpeg_remap_with_our_maps_gives_our_nearest_neighbour_output(tmp_path: Path) -> None:
    table = fisheye_table()
    save_table(table, tmp_path / "cam.npz")
    frame = np.random.default_rng(7).integers(0, 256, (IMAGE_SIZE[1], IMAGE_SIZE[0], 3), dtype=np.uint8)
    cv2.imwrite(str(tmp_path / "frame.png"), frame)
    # Wide and steep: part of the view has no source (beyond the horizon), so the fill is checked too.
    options = ["--yaw-deg", 30, "--pitch-deg", -20, "--roll-deg", 10, "--fov-deg", 140, "--size", "200x150"]
    result = CliRunner().invoke(
        main,
        [
            str(a)
            for a in [
                "perspective",
                tmp_path / "cam.npz",
                tmp_path / "frame.png",
                "-o",
                tmp_path / "ours.png",
                "--interp",
                "nearest",
                "--save-map",
                tmp_path / "map.npy",
                "--save-map-pgm",
                tmp_path / "map",
                *options,
            ]
        ],
    )
    assert result.exit_code == 0, result.output
    assert f"and {tmp_path / 'map_x.pgm'} and {tmp_path / 'map_y.pgm'}" in result.output
    command = [
        imageio_ffmpeg.get_ffmpeg_exe(),
        "-v",
        "error",
        "-i",
        str(tmp_path / "frame.png"),
        "-i",
        str(tmp_path / "map_x.pgm"),
        "-i",
        str(tmp_path / "map_y.pgm"),
        "-lavfi",
        "[0:v][1:v][2:v]remap=format=color:fill=black",
        "-frames:v",
        "1",
        "-pix_fmt",
        "rgb24",
        str(tmp_path / "ffmpeg.png"),
    ]
    subprocess.run(command, check=True, capture_output=True, timeout=60)
    theirs = cv2.imread(str(tmp_path / "ffmpeg.png"), cv2.IMREAD_UNCHANGED)
    ours = cv2.imread(str(tmp_path / "ours.png"), cv2.IMREAD_UNCHANGED)
    map_uv = np.load(tmp_path / "map.npy")
    no_source = ~np.all(np.isfinite(map_uv), axis=2)
    assert theirs.shape == ours.shape == (150, 200, 3)
    assert 0.05 < no_source.mean() < 0.6
    # The PGM planes hold rint of the map, and cv2.remap's nearest neighbour rounds the
    # same float32 map the same way (half to even), so the two agree everywhere; only a
    # position exactly on a .5 tie could ever go either way, so those pixels are let off.
    ties = np.any(np.abs(np.abs(map_uv - np.floor(map_uv)) - 0.5) < 1e-6, axis=2)
    differ = np.any(theirs != ours, axis=2)
    assert not np.any(differ & ~ties), f"{int(np.sum(differ & ~ties))} pixels differ"
    assert np.all(theirs[no_source] == 0)
    # And both are the view we meant: the map against the fisheye's own projection (r = 95 alpha),
    # applied by the library.
    fisheye = RadialCamera(
        name="equidistant", law="equidistant", scale=95.0, image_size=IMAGE_SIZE, centre=(159.5, 149.5),
        s=-1, phi0=0.4, alpha_max=math.pi / 2,
    )  # fmt: skip
    rays = perspective_directions(math.radians(30), math.radians(-20), math.radians(10), math.radians(140), (200, 150))
    assert_map_sees_like_the_camera(map_uv, fisheye, rays)
    np.testing.assert_array_equal(ours, Remapper(map_uv, IMAGE_SIZE, "nearest")(frame))
