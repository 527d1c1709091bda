"""Issue 55, section 2 (hardening 5): the fuzz classes an outside check found, each pinned.

A table's metadata of numbers no float holds or no camera has (D, E); a named pipe given to ``fit`` (B);
a non-central table exported to a single-viewpoint format (F); forced fit options kept or refused (G);
streams without an index seeked as ffmpeg seeks them (C); the Python API's wrong inputs (I); repeated
pictures counted once (H).
"""

from __future__ import annotations

import json
import math
import os
import re
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import av
import cv2
import numpy as np
import pytest

from panomap.errors import PanomapError
from panomap.simulate import standard_cameras
from panomap.table.file import load_table, metadata_digest

from helpers import assert_one_line_error, hyperbolic_inputs, run

SIZE = (400, 400)


@pytest.fixture(scope="module")
def inputs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder with a table fitted to a simulated hyperbolic camera (fit.npz), the same table with ray
    origins 30 mm apart (vp.npz, format version 4) and an image of its size (omni.png)."""
    folder = tmp_path_factory.mktemp("hardening5")
    hyperbolic_inputs(folder, SIZE, (201.3, 196.2), 40, "fit.npz")
    tamper(folder / "fit.npz", folder / "vp.npz", with_viewpoint)
    return folder


def tamper(source: Path, target: Path, edit: Callable[[dict[str, Any]], None]) -> Path:
    """``source``'s table with its metadata edited by ``edit`` and its checksum recomputed, as ``target``."""
    with np.load(source) as archive:
        entries, meta = archive["entries"], json.loads(str(archive["meta"][()]))
    edit(meta)
    meta["metadata_sha256"] = metadata_digest(meta)
    np.savez(target, entries=entries, meta=np.array(json.dumps(meta)))
    return target


def with_viewpoint(meta: dict[str, Any], spread: float = 0.03) -> None:
    """Ray origins ``spread`` world units apart over the table's elevations (format version 4); the entries
    (f_r) stay what they are."""
    low, high = meta["elevation_range_rad"]
    meta["version"] = 4
    meta["model"]["viewpoint"] = {"elevations_rad": [low, high], "offsets": [0.0, spread]}


def view_commands(folder: Path, table: Path) -> dict[str, list[object]]:
    return {
        "info": ["info", table],
        "panorama": ["panorama", table, folder / "omni.png", "-o", folder / "out" / "p.png", "--size", "64x16"],
        "video": ["video", table, folder / "omni.png", "-o", folder / "out" / "v.mp4", "--view", "panorama:size=64x16"],
    }


# ----------------------------------------------------------------------------- D: numbers no float holds

HUGE = 10**400


def set_at(path: str) -> Callable[[dict[str, Any]], None]:
    """An edit that puts a 400-digit integer at ``path`` (``model.centre.0``: keys and list indices)."""

    def edit(meta: dict[str, Any]) -> None:
        if path.startswith("model.viewpoint"):
            with_viewpoint(meta)
        *parents, last = path.split(".")
        node: Any = meta
        for key in parents:
            node = node[int(key)] if isinstance(node, list) else node[key]
        node[int(last) if isinstance(node, list) else last] = HUGE

    return edit


FIELDS = ["model.viewpoint.offsets.1", "camera_position.0", "model.centre.1", "info.fit.rms_px", "model.phi0_rad"]


@pytest.mark.parametrize("command", ["info", "panorama", "video"])
@pytest.mark.parametrize("field", FIELDS)
def test_a_400_digit_integer_in_a_tables_metadata_is_named(
    inputs: Path, tmp_path: Path, field: str, command: str
) -> None:
    # An OverflowError traceback in info, video and view: JSON reads the integer, no float holds it.
    table = tamper(inputs / "fit.npz", tmp_path / "cam.npz", set_at(field))
    (inputs / "out").mkdir(exist_ok=True)
    result = run(*view_commands(inputs, table)[command])
    named = re.sub(r"\.(\d+)", r"[\1]", field)  # (as the error names it: model.centre[1])
    assert_one_line_error(result, str(table), named, "not a finite number", exit_code=1)
    assert not list((inputs / "out").iterdir())


# ----------------------------------------------------------------------------- E: ray origins no mirror has


@pytest.mark.parametrize("offsets", [[0.0, 1e300], [-1e300, 0.0], [0.0, 2e9]])
def test_ray_origins_beyond_any_mirror_are_refused_on_load(inputs: Path, tmp_path: Path, offsets: list[float]) -> None:
    # 1e300 loaded: views exited 0 with 0% of their pixels filled and NumPy overflow warnings.
    table = tamper(inputs / "vp.npz", tmp_path / "cam.npz", lambda m: m["model"]["viewpoint"].update(offsets=offsets))
    (tmp_path / "out").mkdir()
    for command in ("info", "panorama"):
        result = run(*view_commands(tmp_path, table)[command])
        assert_one_line_error(result, str(table), "viewpoint's offsets", "beyond 1e+09", exit_code=1)
    with pytest.raises(PanomapError, match="viewpoint's offsets"):
        load_table(table)


def test_a_camera_position_or_centre_beyond_any_room_is_refused_on_load(inputs: Path, tmp_path: Path) -> None:
    for key, edit in (
        ("camera_position", lambda m: m.update(camera_position=[1e300, 0.0, 0.0])),
        ("model.centre", lambda m: m["model"].update(centre=[200.0, -1e12])),
    ):
        table = tamper(inputs / "fit.npz", tmp_path / "cam.npz", edit)
        assert_one_line_error(run("info", table), str(table), key, "beyond 1e+09", exit_code=1)


def test_a_table_with_ray_origins_within_the_limits_still_loads(inputs: Path) -> None:
    result = run("info", inputs / "vp.npz")
    assert result.exit_code == 0, result.output + result.stderr
    assert "0.03 world units" in result.output


# ----------------------------------------------------------------------------- B: a named pipe as an input


@contextmanager
def unblocked_after(fifo: Path, seconds: float) -> Iterator[None]:
    """Open ``fifo``'s writing end after ``seconds`` (and close it: end of file), so that a reader blocked on
    it, the fault pinned, fails the test instead of hanging it."""
    done = threading.Event()

    def writer() -> None:
        if done.wait(seconds):
            return
        while not done.is_set():
            try:
                os.close(os.open(fifo, os.O_WRONLY | os.O_NONBLOCK))
            except OSError:  # (no reader yet: ENXIO)
                pass
            time.sleep(0.05)

    thread = threading.Thread(target=writer, daemon=True)
    thread.start()
    try:
        yield
    finally:
        done.set()
        thread.join()


@pytest.mark.parametrize("option", ["--image", "--video"])
def test_a_named_pipe_given_to_fit_is_not_a_file(inputs: Path, tmp_path: Path, option: str) -> None:
    # fit --video and fit --image opened it (the memory check reads the pictures' headers) and waited for a
    # writer for ever; every other command answers "not a file".
    fifo = tmp_path / ("pipe.mp4" if option == "--video" else "pipe.png")
    os.mkfifo(fifo)
    started = time.monotonic()
    with unblocked_after(fifo, 3.0):
        result = run("fit", "-o", tmp_path / "cam.npz", "--image", inputs / "omni.png", option, fifo)
    assert_one_line_error(result, str(fifo), "not a file", exit_code=1)
    assert time.monotonic() - started < 3
    assert not (tmp_path / "cam.npz").exists()


def test_a_missing_video_given_to_fit_is_no_such_file(tmp_path: Path) -> None:
    # It was "is not a video panomap can decode".
    result = run("fit", "-o", tmp_path / "cam.npz", "--video", tmp_path / "missing.mp4")
    assert_one_line_error(result, str(tmp_path / "missing.mp4"), "no such file", exit_code=1)


# ----------------------------------------------------------------------------- F: export of a non-central table


@pytest.mark.parametrize("format_", ["ocam", "kalibr-ds", "opencv-omnidir"])
def test_exporting_ray_origins_to_a_single_viewpoint_format_is_refused(
    inputs: Path, tmp_path: Path, format_: str
) -> None:
    # It wrote a single-viewpoint model, "largest difference 1.17 px", with no word of the 30 mm dropped.
    out = tmp_path / "calib.txt"
    result = run("export", inputs / "vp.npz", "-o", out, "--format", format_)
    assert_one_line_error(result, str(inputs / "vp.npz"), f"{format_} has a single viewpoint", "0.03 world units",
                          "30.0 mm", exit_code=1)  # fmt: skip
    assert not out.exists()


def test_a_negligible_spread_of_ray_origins_is_exported(inputs: Path, tmp_path: Path) -> None:
    table = tamper(inputs / "fit.npz", tmp_path / "cam.npz", lambda m: with_viewpoint(m, spread=1e-9))
    result = run("export", table, "-o", tmp_path / "calib.txt", "--format", "ocam")
    assert result.exit_code == 0, result.output + result.stderr
    assert (tmp_path / "calib.txt").exists()


# ----------------------------------------------------------------------------- G: forced options kept or refused


@pytest.fixture(scope="module")
def sphere_landmarks(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[object]]:
    """Landmarks (lm.csv) of a spherical mirror camera whose rays leave the axis over 53 mm (20, at 1-6 m, as
    tests/test_noncentral.py's), and the options that place them (camera, centre, radii, image size)."""
    folder = tmp_path_factory.mktemp("sphere")
    base = standard_cameras(size=(1600, 1600), seed=0)["spherical"]
    camera = base.with_mirror(0.3, 0.3, math.radians(25.0))
    rng, position = np.random.default_rng(5), np.array([0.0, 0.0, 2.0])
    rows = ["u,v,X,Y,Z"]
    while len(rows) <= 20:
        distance, rho, theta = rng.uniform(1.0, 6.0), math.radians(rng.uniform(-70, 5)), rng.uniform(0, 2 * math.pi)
        d = distance * np.array([math.cos(theta), math.sin(theta), math.tan(rho)])
        uv = camera.project(d)
        if np.all(np.isfinite(uv)):
            rows.append(",".join(map(str, [*uv, *(position + d)])))
    (folder / "lm.csv").write_text("\n".join(rows) + "\n")
    options = ["--camera", *position, "--centre", *camera.centre, "--cutoff-radius", camera.cutoff_radius,
               "--outer-radius", camera.outer_radius, "--image-size", "1600x1600"]  # fmt: skip
    return folder / "lm.csv", options


@pytest.mark.slow
def test_a_forced_model_is_kept_with_forced_ray_origins(sphere_landmarks, tmp_path: Path) -> None:
    # --model odd1 --viewpoint caustic was reported "odd3 (forced)": the caustic's search replaced the model.
    landmarks, options = sphere_landmarks
    out = tmp_path / "cam.npz"
    result = run("fit", landmarks, *options, "-o", out, "--model", "odd1", "--viewpoint", "caustic")
    assert result.exit_code == 0, result.output + result.stderr
    assert "radial model: odd1 (forced)" in result.output
    table = load_table(out)
    assert table.model.radial.kind == "odd1" and not table.model.single_viewpoint


@pytest.mark.parametrize(
    ("options", "named"),
    [
        (
            ["--sphere-radius", 0.3, "--model", "fisheye"],
            "--model fisheye does not go with it",
        ),  # was "sphere (forced)"
        (["--viewpoint", "caustic", "--model", "paper"], "does not go with --model paper"),  # was single-viewpoint
        (["--viewpoint", "caustic", "--azimuth", "paper"], "does not go with --azimuth paper"),
        (["--sphere-radius", 0.3, "--azimuth", "paper"], "does not go with --azimuth paper"),
    ],
)
def test_ray_origins_with_options_that_replace_them_are_refused(
    sphere_landmarks, tmp_path: Path, options: list[object], named: str
) -> None:
    landmarks, placing = sphere_landmarks
    result = run("fit", landmarks, *placing, "-o", tmp_path / "cam.npz", *options)
    assert_one_line_error(result, named, exit_code=2)
    assert not (tmp_path / "cam.npz").exists()


def test_the_python_fit_refuses_them_too(sphere_landmarks) -> None:
    from panomap import calibrate_camera
    from panomap.calibrate.landmarks.pairs import read_landmarks

    landmarks, _ = sphere_landmarks
    with pytest.raises(PanomapError, match="does not go with --model paper"):
        calibrate_camera(
            read_landmarks(landmarks), (0.0, 0.0, 2.0), centre=(800.0, 800.0), model="paper", viewpoint="caustic"
        )


# ----------------------------------------------------------------------------- one-liners


def small_video(path: Path, rotation_deg: int = 0, frames: int = 5, size: tuple[int, int] = (64, 48)) -> Path:
    """A short H.264 video (``frames`` frames at 10 fps, grey levels), its display matrix turning it by
    ``rotation_deg``."""
    with av.open(str(path), "w") as container:
        stream = container.add_stream("libx264", rate=10)
        stream.width, stream.height, stream.pix_fmt = size[0], size[1], "yuv420p"
        if rotation_deg:
            stream.set_display_rotation(rotation_deg)
        for k in range(frames):
            frame = av.VideoFrame.from_ndarray(np.full((size[1], size[0], 3), 40 * k % 256, np.uint8), format="bgr24")
            for packet in stream.encode(frame):
                container.mux(packet)
        for packet in stream.encode():
            container.mux(packet)
    return path


def test_a_videos_rotation_metadata_is_warned_of(inputs: Path, tmp_path: Path) -> None:
    # Pictures got a warning for their EXIF orientation; a video's display matrix was ignored without a word.
    turned = small_video(tmp_path / "turned.mp4", rotation_deg=90)
    video = ["video", inputs / "fit.npz", turned, "-o", tmp_path / "out.mp4", "--view", "panorama:size=64x16"]
    for args in (["centre", turned], ["fit", "-o", tmp_path / "cam.npz", "--image", turned], video):
        result = run(*args)
        assert f"panomap: warning: {turned}: it asks players to turn its frames by 90 deg" in result.stderr, args
    plain = small_video(tmp_path / "plain.mp4")
    assert "turn its frames" not in run("centre", plain).stderr
    # (video reads it beside the table, on a thread: a table refused meanwhile gets its one line alone)
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a table")
    assert_one_line_error(run("video", bad, turned, "-o", tmp_path / "no.mp4", "--view", "panorama:size=64x16"),
                          "bad.npz", "not a")  # fmt: skip


def test_the_video_note_escapes_the_files_name(tmp_path: Path) -> None:
    # The note named the file as it is: an escape sequence in the name reached the terminal.
    video = small_video(tmp_path / "a\x1b[31m.mp4")
    result = run("fit", "-o", tmp_path / "cam.npz", "--video", video)
    assert "note: " + str(tmp_path / "a\\x1b[31m.mp4: 8 frames taken") in result.stderr
    assert "\x1b" not in result.stderr


def test_kalibr_numbers_written_as_yaml_1_2_writes_them_are_read(tmp_path: Path) -> None:
    # YAML 1.1 reads 1e-5 (no dot) as text: the file was refused as "not a list of numbers".
    path = tmp_path / "camchain.yaml"
    path.write_text(
        "cam0:\n  camera_model: omni\n  intrinsics: [0.8, 300.0, 300.0, 373.5, 239.5]\n  distortion_model: radtan\n"
        "  distortion_coeffs: [1e-5, -2E-4, 0.0, 1e-6]\n  resolution: [748, 480]\n"
    )
    result = run("import", path, "-o", tmp_path / "cam.npz")
    assert result.exit_code == 0, result.output + result.stderr
    path.write_text(path.read_text().replace("1e-6]", "1e-6x]"))
    assert_one_line_error(run("import", path, "-o", tmp_path / "cam.npz"), "not a list of numbers", exit_code=1)


# ----------------------------------------------------------------------------- C: streams without an index


def grey_video(path: Path, container_format: str, size: int = 400, frames: int = 60, gop: int | None = None) -> Path:
    """``frames`` frames at 25 fps, frame k of grey level 4k (one keyframe only, x264's default, unless ``gop``)."""
    with av.open(str(path), "w", format=container_format) as container:
        stream = container.add_stream("libx264", rate=25)
        stream.width, stream.height, stream.pix_fmt = size, size, "yuv420p"
        if gop:
            stream.options = {"g": str(gop)}
        for k in range(frames):
            frame = av.VideoFrame.from_ndarray(np.full((size, size, 3), 4 * k, np.uint8), format="bgr24")
            frame.pts = k
            for packet in stream.encode(frame):
                container.mux(packet)
        for packet in stream.encode():
            container.mux(packet)
    return path


@pytest.mark.parametrize(("name", "container_format", "gop"),
                         [("a.ts", "mpegts", None), ("b.ts", "mpegts", 10), ("c.h264", "h264", None),
                          ("d.mp4", "mp4", None)])  # fmt: skip
def test_a_frame_at_a_time_is_found_in_a_stream_without_an_index(
    tmp_path: Path, name: str, container_format: str, gop: int | None
) -> None:
    # MPEG-TS landed a keyframe past the time or on no keyframe (nothing decoded), raw H.264 (no timestamps)
    # failed its seek: "cannot read it as an image", "no frame of it could be decoded".
    from panomap.video.source import first_frame

    video = grey_video(tmp_path / name, container_format, size=64, gop=gop)
    with av.open(str(video)) as container:
        every = [frame.to_ndarray(format="bgr24") for frame in container.decode(video=0)]  # (read from the start)
    assert len(every) == 60
    for at_s, k in ((0.0, 0), (0.5, 12), (1.0, 25), (2.0, 50)):
        frame = first_frame(video, 10**8, at_s)
        assert frame is not None, at_s
        assert np.array_equal(frame, every[k]), (at_s, float(frame.mean()), float(every[k].mean()))


@pytest.mark.parametrize("name", ["v.ts", "v.h264"])
def test_video_from_a_start_reads_every_frame_after_it(inputs: Path, tmp_path: Path, name: str) -> None:
    # --start 1 lost 5 of the 35 frames of the MPEG-TS, and every frame of raw H.264; the .mp4 had all 35.
    video = grey_video(tmp_path / name, "mpegts" if name.endswith(".ts") else "h264")
    for start, frames in ((0, 60), (1, 35)):
        out = tmp_path / f"out{start}.mp4"
        result = run("video", inputs / "fit.npz", video, "-o", out, "--view", "panorama:size=64x16", "--start", start)
        assert result.exit_code == 0, result.output + result.stderr
        assert f"unwarped {frames} frames" in result.output


# ----------------------------------------------------------------------------- H: repeated pictures counted once


def test_repeated_pictures_given_to_learn_from_images_count_once(inputs: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # learn_from_images([img] * 100) ran past 240 s (one copy: 13 s): each copy's lines were searched again.
    import panomap.calibrate.pictures as pictures

    image = cv2.imread(str(inputs / "omni.png"))
    other = image[::-1].copy()
    searched: list[list[object]] = []

    def stop(omnis, names, *args):  # the search, recorded and stopped (its work is not what is pinned)
        searched.append(list(names))
        raise PanomapError("stopped")

    monkeypatch.setattr(pictures, "_learn", stop)
    with pytest.raises(PanomapError, match="stopped"):
        pictures.learn_from_images([image] * 50 + [other, image.copy()], names=[f"p{k}" for k in range(52)])
    assert searched == [["p0", "p50"]]
