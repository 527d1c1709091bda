"""Hardening 6: the command line fuzzed command by command; each fault found is pinned here.

A floor view's resolution too fine for any image (C1); an encoder's own refusal, which went past FFmpeg's log
(x264 on stderr) or was hidden behind "Generic error" (a frame wider than the encoder takes) (C2); a rig's
``--each`` pattern and its cameras' names, which go into file names (C3).
"""

from __future__ import annotations

import json
import shutil
import zipfile
from collections.abc import Callable
from pathlib import Path

import av
import cv2
import pytest

from panomap.calibrate.circles.types import Circle, ImageCircles
from panomap.calibrate.lines.orientation import pixel_world_azimuth, zero_azimuth
from panomap.errors import PanomapError
from panomap.interop.readers.json_text import load_json
from panomap.rig import CameraRig
from panomap.table.file import load_table
from panomap.video.output import EncoderSettings, probe_refusal
from panomap.views.floor import FloorView
from test_rig import BACK_TO_BACK, camchain

from helpers import assert_one_line_error, hyperbolic_inputs, run, write_clip

SIZE = (240, 240)


@pytest.fixture(scope="module")
def inputs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder with a table fitted to a simulated hyperbolic camera (cam.npz), the same table twice as
    front.npz and back.npz, their rig (rig.npz), an image of its size (omni.png) and an out/ folder."""
    folder = tmp_path_factory.mktemp("hardening6")
    hyperbolic_inputs(folder, SIZE, (121.3, 118.2), 30, "cam.npz")
    for name in ("front", "back"):
        shutil.copy(folder / "cam.npz", folder / f"{name}.npz")
    (folder / "out").mkdir()
    result = run("rig", "make", folder / "front.npz", folder / "back.npz", "-o", folder / "rig.npz")
    assert result.exit_code == 0, result.output + result.stderr
    return folder


def written(folder: Path) -> list[str]:
    return sorted(path.name for path in folder.iterdir())


# ----------------------------------------------------------------------------- C1: a resolution too fine


@pytest.mark.parametrize(("x_range", "shown"), [((0.0, 6.0), "6e+300 x 5e+300"), ((-1e9, 1e9), "inf x 5e+300")])
def test_a_floor_resolution_too_fine_for_any_image_is_refused_in_a_short_line(
    inputs: Path, x_range: tuple[float, float], shown: str
) -> None:
    """It printed the image's width as a 300-digit integer, and over a wide extent failed with OverflowError's
    traceback (the width rounded from infinity)."""
    with pytest.raises(PanomapError, match="too large") as error:
        FloorView.with_resolution(0.0, x_range, (0.0, 5.0), 1e-300)
    assert shown in str(error.value) and len(str(error.value)) < 160
    out = inputs / "out" / "floor.png"
    result = run("floor", inputs / "cam.npz", inputs / "omni.png", "-o", out, "--z", 0, "--x", *x_range,
                 "--y", 0, 5, "--resolution", 1e-300)  # fmt: skip
    assert_one_line_error(result, f"an image of {shown} px: too large", exit_code=2)
    assert not out.exists()


def test_a_fine_resolution_within_the_limits_still_gives_its_size() -> None:
    assert FloorView.with_resolution(0.0, (0.0, 6.0), (0.0, 5.0), 0.01).size == (600, 500)
    assert FloorView.with_resolution(0.0, (0.0, 6.0), (0.0, 5.0), 1e3).size == (1, 1)


# ----------------------------------------------------------------------------- C2: the encoder's own words


@pytest.mark.parametrize(
    ("options", "reason"),
    [
        (["--preset", "nope"], "invalid preset 'nope'"),
        (["--encoder-option", "tune=nope"], "invalid tune 'nope'"),
    ],
)
def test_x264s_own_refusal_is_the_reason_and_nothing_else_is_printed(
    inputs: Path, capfd: pytest.CaptureFixture[str], options: list[str], reason: str
) -> None:
    """x264 printed "x264 [error]: invalid preset 'nope'" to the process's stderr itself, a second line beside
    ours, which said only "Invalid argument" (and ``batch`` refused it on the cluster, for every video). The
    options are now tried before any work: a usage error."""
    out = inputs / "out" / "x264.mp4"
    result = run("video", inputs / "cam.npz", inputs / "omni.png", "-o", out, "--view", "panorama:size=64x16",
                 *options)  # fmt: skip
    assert_one_line_error(result, "the video encoder libx264 refused its options", reason, exit_code=2)
    assert "x264 [error]" not in capfd.readouterr().err
    assert not out.exists()


def test_the_encoders_words_are_the_reason_on_a_retry_too() -> None:
    """PyAV drops a log line that repeats the one before: a batch's retry of a refused output said only
    "Generic error in an external library"."""
    settings = EncoderSettings(preset="nope")
    first, second = probe_refusal(settings), probe_refusal(settings)
    assert first is not None and "invalid preset 'nope'" in first and "Error setting preset" in first
    assert second == first
    assert probe_refusal(EncoderSettings()) is None


def test_batch_refuses_an_encoder_option_once_before_the_cluster(inputs: Path, tmp_path: Path) -> None:
    clip = tmp_path / "clip.mp4"
    write_clip(clip, [cv2.imread(str(inputs / "omni.png"))] * 2, 5)
    result = run(*BATCH, clip, "--table", inputs / "cam.npz", "-o", f"{tmp_path}/{{stem}}_{{name}}.mp4",
                 "--preset", "nope", "--record", tmp_path / "record.jsonl")  # fmt: skip
    assert_one_line_error(result, "refused its options (preset=nope, crf=20): invalid preset 'nope'", exit_code=2)
    assert sorted(path.name for path in tmp_path.iterdir()) == ["clip.mp4"]


def test_a_frame_wider_than_the_encoder_takes_is_said_so(inputs: Path) -> None:
    """x264 takes frames up to 16384 px a side: a wider view said "refused its options (preset=veryfast,
    crf=20): Generic error in an external library", blaming the options."""
    out = inputs / "out" / "wide.mp4"
    result = run("video", inputs / "cam.npz", inputs / "omni.png", "-o", out, "--view", "equirect:size=16386x64")
    assert_one_line_error(result, "wide.mp4: the video encoder libx264 cannot encode frames of 16386 x 64",
                          "16386x64", "give the view a smaller size")  # fmt: skip
    assert not out.exists()


def test_an_encoder_that_opens_still_writes_the_video(inputs: Path) -> None:
    out = inputs / "out" / "fine.mp4"
    result = run("video", inputs / "cam.npz", inputs / "omni.png", "-o", out, "--view", "panorama:size=64x16", "-q")
    assert result.exit_code == 0 and result.stderr == "", result.stderr
    with av.open(str(out)) as container:  # the one picture's frame, at the view's size (not a header alone)
        shapes = [frame.to_ndarray(format="bgr24").shape for frame in container.decode(video=0)]
    assert shapes == [(16, 64, 3)], shapes


# ----------------------------------------------------------------------------- C3: a rig's names in file names


@pytest.mark.parametrize(
    ("pattern", "message"),
    [
        ("{camera}{0}.png", "unknown placeholder {0}: the only one is {camera}"),
        ("{camera}{x}.png", "unknown placeholder {x}"),
        ("{camera.__class__}.png", "unknown placeholder {camera.__class__}"),
        ("{camera:>9}.png", "unknown placeholder {camera:>9}"),
        ("{camera}{.png", "is malformed (expected '}' before end of string"),
        ("{camera}}.png", "is malformed (Single '}'"),
        ("{{camera}}.png", "has no {camera} to put each camera's name in"),
    ],
)
def test_an_each_pattern_with_any_other_placeholder_is_refused(inputs: Path, pattern: str, message: str) -> None:
    """IndexError's, KeyError's or ValueError's traceback; {camera.__class__} wrote "<class 'str'>front.png"."""
    out = inputs / "out"
    before = written(out)
    result = run("equirect", inputs / "rig.npz", inputs / "omni.png", inputs / "omni.png", "-o", out / "r.png",
                 "--size", "64x32", "--each", f"{out}/{pattern}")  # fmt: skip
    assert_one_line_error(result, "'--each'", message, exit_code=2)
    assert written(out) == before


@pytest.mark.parametrize("name", ["../../x", "a/b", "a\\b", "..", " ", "", "\x1b[31m", "a\u202eb", "n" * 65])
def test_a_camera_name_that_cannot_name_a_file_is_refused(inputs: Path, name: str) -> None:
    """``--each 'out/{camera}.png'`` with a camera named ../../x wrote two folders up; an escape sequence went
    to the terminal and into a file name."""
    tables = (load_table(inputs / "cam.npz"),) * 2
    with pytest.raises(PanomapError, match="cannot name a file"):
        CameraRig(tables, (name, "back"))
    out = inputs / "out" / "named.npz"
    result = run("rig", "make", inputs / "front.npz", inputs / "back.npz", "--name", name, "--name", "b", "-o", out)
    assert_one_line_error(result, "cannot name a file: 1 to 64 characters, no / or \\", "not blank, . or ..")
    assert "\x1b" not in result.stderr and not out.exists()


def test_a_rig_file_edited_to_hold_such_a_name_is_refused(inputs: Path, tmp_path: Path) -> None:
    edited = tmp_path / "edited.npz"
    with zipfile.ZipFile(inputs / "rig.npz") as source, zipfile.ZipFile(edited, "w") as target:
        for item in source.infolist():
            data = source.read(item)
            if item.filename == "rig.json":
                index = json.loads(data)
                index["names"][1] = "../../x"
                data = json.dumps(index).encode()
            target.writestr(item, data)
    result = run("equirect", edited, inputs / "omni.png", inputs / "omni.png", "-o", tmp_path / "r.png",
                 "--size", "64x32", "--each", f"{tmp_path}/{{camera}}.png")  # fmt: skip
    assert_one_line_error(result, "edited.npz: the rig is malformed (camera name '../../x' cannot name a file")
    assert written(tmp_path) == ["edited.npz"]


def test_tables_of_one_file_name_are_told_to_be_named(inputs: Path, tmp_path: Path) -> None:
    """It said "a rig needs one name per camera, each its own", not which name or how to give others."""
    (tmp_path / "a").mkdir()
    shutil.copy(inputs / "cam.npz", tmp_path / "a" / "cam.npz")
    out = tmp_path / "rig.npz"
    result = run("rig", "make", inputs / "cam.npz", tmp_path / "a" / "cam.npz", "-o", out)
    assert_one_line_error(result, "(cam twice)", "named after their tables' files; name each with --name", exit_code=2)
    result = run("rig", "make", inputs / "front.npz", inputs / "back.npz", "--name", "x", "--name", "x", "-o", out)
    assert_one_line_error(result, "a rig needs one name per camera, each its own (x twice)")
    assert not out.exists()


# ----------------------------------------------------------------------------- C4: a CSV's column given twice


@pytest.mark.parametrize(
    ("command", "header", "message"),
    [
        ("unproject", "u,u,v", "holds u 2 times (columns 1, 2)"),
        ("unproject", "U,v,u", "holds u 2 times (columns 1, 3)"),
        ("fit", "name,u,v,X,Y,Z,x", "holds X 2 times (columns 4, 7)"),
    ],
)
def test_a_csv_holding_a_column_twice_is_refused(inputs: Path, tmp_path: Path, command: str, header: str,
                                                 message: str) -> None:  # fmt: skip
    """The columns are found in any case: the first of two was taken, silently (u,u,v read u from column 1)."""
    points = tmp_path / "points.csv"
    if command == "fit":
        points.write_text(f"{header}\n" + "".join(f"a{k},{10 * k},20,3,4,0,1\n" for k in range(6)))
        out = tmp_path / "cam.npz"
        args = [points, "-o", out, "--camera", 0.3, -0.2, 2.5, "--centre", 120, 120, "--image-size", "240x240"]
    else:
        points.write_text(f"{header}\n100,110,120\n")
        out = tmp_path / "rays.csv"
        args = [inputs / "cam.npz", points, "-o", out]
    result = run(command, *args)
    assert_one_line_error(result, "points.csv: the CSV's header holds", message, "keep one")
    assert not out.exists()


# ----------------------------------------------------------------------------- C5: a table or a rig not .npz


@pytest.mark.parametrize(
    ("command", "what"),
    [
        (["import", "{omni.png}", "-o", "{out}/t.png"], "a table (or a rig)"),
        (["orient", "{cam.npz}", "-o", "{out}/t.png", "--orientation", 0, 0, 0], "a table"),
        (["level", "{cam.npz}", "{omni.png}", "-o", "{out}/t"], "a table"),
        (["rig", "make", "{front.npz}", "{back.npz}", "-o", "{out}/r.zip"], "a rig"),
        (["rig", "learn", "{rig.npz}", "{omni.png}", "{omni.png}", "-o", "{out}/r.png"], "a rig"),
        (["rig", "learn", "--side-by-side", "{omni.png}", "-o", "{out}/r.json"], "a rig"),
        (["rig", "place", "{rig.npz}", "{omni.png}", "{omni.png}", "-o", "{out}/r.npy"], "a rig"),
    ],
)
def test_a_table_or_rig_named_other_than_npz_is_refused_before_any_work(
    inputs: Path, tmp_path: Path, command: list[object], what: str
) -> None:
    """``fit`` refused ``-o cam.png``; import, orient, level and the rig commands wrote a table or a rig under
    any name (cam.png, which every other program takes for a broken picture)."""
    files = {f"{{{path.name}}}": str(path) for path in inputs.iterdir()} | {"{out}": str(tmp_path)}
    args = [files.get(str(arg), str(arg)).replace("{out}", str(tmp_path)) for arg in command]
    result = run(*args)
    assert_one_line_error(result, "'-o'", f"{what} is written as .npz (name it so)", exit_code=2)
    assert list(tmp_path.iterdir()) == []


# ----------------------------------------------------------------------------- C6: batch's job-wide refusals


BATCH = ["batch", "--workers", "1", "--view", "panorama:size=64x16"]


@pytest.mark.parametrize("table", ["omni.png", "empty.npz"])
def test_a_batch_table_that_is_no_table_is_refused_once_before_the_cluster(
    inputs: Path, tmp_path: Path, table: str
) -> None:
    """Each input's task failed on the cluster (after its retries), one line each, then the summary."""
    (inputs / "empty.npz").touch()
    record = tmp_path / "record.jsonl"
    result = run(*BATCH, inputs / "omni.png", "--table", inputs / table,
                 "-o", f"{tmp_path}/{{stem}}_{{name}}.png", "--record", record)  # fmt: skip
    assert_one_line_error(result, f"{table}: not a panomap table")
    assert list(tmp_path.iterdir()) == []


def test_a_batch_video_whose_output_is_no_video_file_is_refused_before_the_cluster(
    inputs: Path, tmp_path: Path
) -> None:
    """The video's task failed on the cluster with "unknown video file type '.png'"."""
    clip = tmp_path / "clip.mp4"
    write_clip(clip, [cv2.imread(str(inputs / "omni.png"))] * 2, 5)
    out = tmp_path / "out"
    out.mkdir()
    result = run(*BATCH, clip, "--table", inputs / "cam.npz", "-o", f"{out}/{{stem}}_{{name}}.png",
                 "--record", tmp_path / "record.jsonl")  # fmt: skip
    assert_one_line_error(result, "clip_panorama.png: unknown video file type '.png'")
    assert list(out.iterdir()) == []


def test_a_batch_camera_name_with_a_control_character_is_refused(inputs: Path, tmp_path: Path) -> None:
    """An escape sequence named a folder of outputs (listing it rewrote the terminal)."""
    result = run(*BATCH, inputs / "omni.png", "--table", inputs / "cam.npz", "--camera", "\x1b[2J",
                 "-o", f"{tmp_path}/{{camera}}/{{stem}}_{{name}}.png", "--record", tmp_path / "r.jsonl")  # fmt: skip
    assert_one_line_error(result, "the camera name '\\x1b[2J' must be a plain name", "control characters")
    assert list(tmp_path.iterdir()) == []


# ----------------------------------------------------------------------------- C7: room on the disk, first


def no_room(monkeypatch: pytest.MonkeyPatch, free: int) -> None:
    """Every disk has ``free`` bytes free."""
    monkeypatch.setattr("panomap.files.shutil.disk_usage", lambda _path: shutil._ntuple_diskusage(10**12, 0, free))


@pytest.mark.parametrize(
    ("options", "named", "needed"),
    [
        (["--save-map", "{out}/m.npy"], "m.npy", "160 kB"),
        (["--save-map-pgm", "{out}/m"], "m_x.pgm", "80 kB"),
    ],
)
def test_a_map_its_disk_has_no_room_for_is_refused_before_any_work(
    inputs: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, options: list[str], named: str, needed: str
) -> None:
    """A full disk was found when the map was written, after the work (each output whole or none, as now)."""
    no_room(monkeypatch, 50_000)
    args = [option.replace("{out}", str(tmp_path)) for option in options]
    result = run("panorama", inputs / "cam.npz", inputs / "omni.png", "-o", tmp_path / "p.png", "--size", "200x100",
                 *args)  # fmt: skip
    assert_one_line_error(result, f"{named}: no room for it: {needed} to write, its disk has 50 kB free")
    assert list(tmp_path.iterdir()) == []
    no_room(monkeypatch, 10**9)
    result = run("panorama", inputs / "cam.npz", inputs / "omni.png", "-o", tmp_path / "p.png", "--size", "200x100",
                 *args, "-q")  # fmt: skip
    assert result.exit_code == 0, result.stderr


def test_a_table_of_a_given_size_its_disk_has_no_room_for_is_refused_before_the_fit(
    inputs: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    marks = tmp_path / "marks.csv"
    marks.write_text("u,v,X,Y,Z\n" + "".join(f"{100 + k},{120 + k},{k},1,0\n" for k in range(6)))
    no_room(monkeypatch, 2_000)
    result = run("fit", marks, "-o", tmp_path / "cam.npz", "--camera", 0, 0, 2, "--centre", 120, 120,
                 "--image-size", "240x240", "--size", "100x50")  # fmt: skip
    assert_one_line_error(result, "cam.npz: no room for it: 40 kB to write, its disk has 2 kB free")
    assert sorted(path.name for path in tmp_path.iterdir()) == ["marks.csv"]


# ----------------------------------------------------------------------------- C8: a host the page cannot listen on


@pytest.mark.parametrize("host", ["no.such.host.invalid", "999.1.1.1"])
def test_a_host_no_page_can_listen_on_is_named_alone(inputs: Path, host: str) -> None:
    """It warned first that the page was "listening on no.such.host.invalid, not loopback", then failed to
    listen and said to choose another port."""
    result = run("view", inputs / "cam.npz", inputs / "omni.png", "--host", host, "--port", 0)
    assert_one_line_error(result, f"cannot listen on {host}:0", "choose another host")
    result = run("learn", inputs / "omni.png", "--host", host, "--port", 0, "--dir", inputs / "out")
    assert result.exit_code == 1 and "not loopback" not in result.stderr  # (a note on the noise's circles first)
    assert "choose another host" in result.stderr.splitlines()[-1], result.stderr


# ----------------------------------------------------------------------------- C9: a rig's file, whole or refused


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda text: text.replace("[0, 0, -1, -0.02]", "[0, 0, -1, .nan]"), "cam1.T_cn_cnm1[2][3] is nan"),
        (lambda text: text.replace("[0, 0, -1, -0.02]", "[0, 0, -1, x]"), "cam1.T_cn_cnm1[2] is [0, 0, -1, 'x']"),
        (lambda text: text.rsplit("  T_cn_cnm1:", 1)[0], "cam2.T_cn_cnm1 is missing"),
        (lambda text: text.replace("cam1:", "cam0:"), "the key 'cam0' is written twice in one map (line 7)"),
    ],
)
def test_a_camchain_with_a_broken_camera_is_refused_not_imported_as_its_first(
    tmp_path: Path, edit: Callable[[str], str], message: str
) -> None:
    """Its rig was not recognised, and camera 0 alone was imported as a table: "wrote cam.npz", exit 0."""
    chain = camchain(tmp_path / "chain.yaml", [BACK_TO_BACK, BACK_TO_BACK])
    chain.write_text(edit(chain.read_text()))
    out = tmp_path / "cam.npz"
    assert_one_line_error(run("import", chain, "-o", out), f"chain.yaml: {message}")
    assert not out.exists()


def test_a_json_key_written_twice_is_refused() -> None:
    """``json`` keeps the last of two, silently (a Basalt calibration's fx written twice)."""
    with pytest.raises(PanomapError, match=r"x\.json: the key 'fx' is written twice in one object"):
        load_json('{"intrinsics": {"fx": 122.5, "fx": 500}}', "x.json")
    assert load_json('{"a": {"fx": 1}, "b": {"fx": 2}}', "x.json") == {"a": {"fx": 1}, "b": {"fx": 2}}


# ----------------------------------------------------------------------------- C10: pixels and pictures given once


@pytest.mark.parametrize(("offset", "radius"), [((0.2, -0.1), "0.2"), ((-5000.0, 0.0), "5000.0"), ((3.0, 0.0), "3.0")])
def test_a_pixel_for_azimuth_zero_outside_the_scene_is_refused(
    inputs: Path, offset: tuple[float, float], radius: str
) -> None:
    """At the centre every azimuth meets (the pixel's azimuth was the centre's noise), and past the image
    circle the camera sees nothing: ``fit --image --azimuth-zero`` took both."""
    model = load_table(inputs / "cam.npz").model
    u0, v0 = model.centre
    circles = ImageCircles((u0, v0), Circle((u0, v0), 110.0, 0.1, 100, 100), None, None)
    with pytest.raises(PanomapError, match=f"is {radius} px from the image centre: give a pixel of the scene, 5 to"):
        zero_azimuth(model, (u0 + offset[0], v0 + offset[1]), circles)
    turned = zero_azimuth(model, (u0 + 60.0, v0), circles)  # (in the ring: taken; its azimuth is now 0)
    assert abs(pixel_world_azimuth(turned, (u0 + 60.0, v0))) < 1e-9


def test_a_picture_given_twice_to_level_is_refused(inputs: Path, tmp_path: Path) -> None:
    """Its vertical lines counted twice (levelling needs 4: two lines given twice passed)."""
    shutil.copy(inputs / "omni.png", tmp_path / "copy.png")
    out = tmp_path / "level.npz"
    for second, how in ((inputs / "omni.png", "the same file"), (tmp_path / "copy.png", "the same bytes")):
        result = run("level", inputs / "cam.npz", inputs / "omni.png", second, "-o", out)
        assert_one_line_error(result, f"are one picture ({how}): give each picture once", exit_code=2)
    assert not out.exists()


# ----------------------------------------------------------------------------- C11: a video's numbers


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (["--bitrate", "100000000000G"], "'--bitrate': '100000000000G': a bit rate is 1 to 100G bit/s"),
        (["--bitrate", "0"], "'--bitrate': '0': a bit rate is 1 to 100G bit/s"),
        (["--timeout", "nan"], "'--timeout': 'nan' is not a finite number"),
        (["--timeout", "inf"], "'--timeout': 'inf' is not a finite number"),
    ],
)
def test_a_videos_absurd_bit_rate_or_timeout_is_a_usage_error(inputs: Path, options: list[str], message: str) -> None:
    """A bit rate past a C long failed with OverflowError's traceback, 0 was taken; a timeout of nan or inf said
    "the reconnect timeout_s must be more than 0 s" (a Python name) with exit 1."""
    out = inputs / "out" / "numbers.mp4"
    result = run("video", inputs / "cam.npz", inputs / "omni.png", "-o", out, "--view", "panorama:size=64x16",
                 *options)  # fmt: skip
    assert_one_line_error(result, message, exit_code=2)
    assert not out.exists()


@pytest.mark.parametrize("segment", ["nan", "inf"])
def test_a_batch_segment_that_is_no_number_is_a_usage_error(inputs: Path, tmp_path: Path, segment: str) -> None:
    """click's FloatRange lets nan through (nan < 1 is false): "the segment length must be more than 0 s"."""
    result = run(*BATCH, inputs / "omni.png", "--table", inputs / "cam.npz", "-o", f"{tmp_path}/{{stem}}.png",
                 "--segment", segment, "--record", tmp_path / "record.jsonl")  # fmt: skip
    assert_one_line_error(result, f"'--segment': '{segment}' is not a finite number", exit_code=2)
