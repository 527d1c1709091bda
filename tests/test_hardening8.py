"""Hardening 8: what hardening 7 left, and the command line fuzzed where it changed last; each fault pinned here.

Refusals found only after the work: a table size too coarse for ``fit``, a view larger than the memory (E1); a
TIFF whose header claims more than its bytes hold (E2); the demo where its disk has no room (E3); a video given
as a rig's picture (E4).
"""

from __future__ import annotations

import json
import shutil
import struct
import zlib
from pathlib import Path

import cv2
import numpy as np
import pytest
from PIL import Image

from helpers import assert_one_line_error, hyperbolic_inputs, run, write_clip

SIZE = (240, 240)


@pytest.fixture(scope="module")
def inputs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder with a table fitted to a simulated hyperbolic camera (cam.npz) and an image of its size
    (omni.png)."""
    folder = tmp_path_factory.mktemp("hardening8")
    hyperbolic_inputs(folder, SIZE, (121.3, 118.2), 30, "cam.npz")
    return folder


def no_room(monkeypatch: pytest.MonkeyPatch, free: int) -> None:
    """Every disk has ``free`` bytes free."""
    monkeypatch.setattr("panomap.files.shutil.disk_usage", lambda _path: shutil._ntuple_diskusage(10**12, 0, free))


# ----------------------------------------------------------------------------- E1: refused before the work


def test_a_table_size_too_coarse_for_the_image_circle_is_refused_before_the_fit(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``fit --size 8x4`` was refused for its chords only once the table was made, after the fit (5.6 s on the
    demo's picture, 1.5 s now): the image circle, given or found, is where the table ends."""
    monkeypatch.setattr("panomap.calibrate.landmarks.pipeline.fit_camera", lambda *a, **k: pytest.fail("the fit ran"))
    marks = tmp_path / "marks.csv"
    marks.write_text("u,v,X,Y,Z\n" + "".join(f"{100 + 9 * k},{120 + 5 * k},{k},1,0\n" for k in range(8)))
    out = tmp_path / "cam.npz"
    result = run("fit", marks, "-o", out, "--camera", 0, 0, 2, "--centre", 120, 120, "--outer-radius", 110,
                 "--size", "8x4")  # fmt: skip
    assert_one_line_error(result, "table size 8x4: between its 8 azimuths the views would be up to 8 px off (the "
                          "image circle's radius 110 px): give M >= 24")  # fmt: skip
    assert not out.exists()


def test_a_view_larger_than_the_memory_available_is_refused_before_its_map_is_made(
    inputs: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A rig's view was checked against the memory, one camera's was not (a plane view takes 57 bytes a pixel,
    measured: 1.8 GB at 8000 x 4000 px); the same check now, with each kind's own figure."""
    from panomap.views import view_kinds

    assert view_kinds()["plane"].bytes_per_pixel > view_kinds()["panorama"].bytes_per_pixel
    monkeypatch.setattr("panomap.io.image_bounds.available_memory", lambda: 50_000_000)
    monkeypatch.setattr("panomap.cli.views.build_map", lambda *a, **k: pytest.fail("the map was made"))
    out = tmp_path / "pano.png"
    result = run("panorama", inputs / "cam.npz", inputs / "omni.png", "-o", out, "--size", "4000x1000")
    assert_one_line_error(result, "a view of 4000 x 1000 px needs about 96 MB of memory, more than the 50 MB "
                          "available: make it smaller")  # fmt: skip
    assert not out.exists()


# ----------------------------------------------------------------------------- E2: a TIFF's claim, held to its bytes


def claiming_tiff(path: Path, size: tuple[int, int], compression: str | None) -> Path:
    """A 16 x 16 px TIFF (Pillow's, ``compression``) whose header is rewritten to claim ``size`` (width, height)."""
    small = np.random.default_rng(1).integers(0, 255, (16, 16, 3), dtype=np.uint8)
    Image.fromarray(small).save(path, **({"compression": compression} if compression else {}))
    data = bytearray(path.read_bytes())
    directory = struct.unpack("<I", data[4:8])[0]
    for entry in range(struct.unpack("<H", data[directory : directory + 2])[0]):
        at = directory + 2 + 12 * entry
        tag, kind = struct.unpack("<HH", data[at : at + 4])
        value = {256: size[0], 257: size[1], 278: size[1]}.get(tag)
        if value is not None:
            data[at + 8 : at + 12] = struct.pack("<HH", value, 0) if kind == 3 else struct.pack("<I", value)
    path.write_bytes(data)
    return path


def directory_first_tiff(path: Path, size: tuple[int, int], cut: int) -> Path:
    """A deflated grey TIFF of random pixels, its directory before its one strip (as some writers place it), the
    file cut ``cut`` bytes short."""
    width, height = size
    strip = zlib.compress(np.random.default_rng(2).integers(0, 255, width * height, dtype=np.uint8).tobytes())
    fields = [(256, width), (257, height), (258, 8), (259, 8), (262, 1), (273, 0), (277, 1), (278, height),
              (279, len(strip))]  # fmt: skip
    start = 8 + 2 + 12 * len(fields) + 4
    entries = b"".join(struct.pack("<HHII", tag, 4, 1, start if tag == 273 else value) for tag, value in fields)
    data = b"II*\x00" + struct.pack("<IH", 8, len(fields)) + entries + bytes(4) + strip
    path.write_bytes(data[:-cut])
    return path


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda p: claiming_tiff(p / "x.tif", (4000, 4000), "tiff_deflate"), "a truncated or corrupt TIFF: its "
         "header claims 4000 x 4000 px, which take at least 47 kB, not"),
        (lambda p: claiming_tiff(p / "x.tif", (240, 240), "tiff_deflate"), "a truncated or corrupt TIFF: ZIPDecode: "
         "Not enough data at scanline 0"),
        (lambda p: claiming_tiff(p / "x.tif", (240, 240), None), "a truncated or corrupt TIFF: its header claims "
         "240 x 240 px, which take at least 173 kB, not"),
        (lambda p: directory_first_tiff(p / "x.tif", (240, 240), 20000), "a truncated TIFF: its pixels' data run to "
         "byte 57748, the file ends at 37748"),
    ],
)  # fmt: skip
def test_a_tiff_whose_header_claims_more_than_its_bytes_hold_is_refused(tmp_path: Path, make, message: str) -> None:
    """The deflated ones were decoded, libtiff's "Not enough data" silenced, the rest black (``panorama`` wrote its
    view of one, exit 0; ``centre`` found no rim); the uncompressed one was said to be a video, its first frame
    taken ("is a video: its first frame is used")."""
    path = make(tmp_path)
    assert_one_line_error(run("centre", path), f"{path.name}: cannot read it as an image ({message}")


@pytest.mark.parametrize("compression", [None, "tiff_deflate", "tiff_lzw", "packbits"])
def test_the_tiff_bound_holds_for_the_flattest_pictures_its_codings_make(tmp_path: Path, compression) -> None:
    from panomap.io.image_bounds import least_file_bytes

    path = tmp_path / "flat.tif"
    Image.fromarray(np.zeros((1500, 2000, 3), np.uint8)).save(path, **({"compression": compression} if compression
                                                                        else {}))  # fmt: skip
    kind, least = least_file_bytes(path, (2000, 1500))  # type: ignore[misc]
    assert kind == "TIFF" and least <= path.stat().st_size, (least, path.stat().st_size)


def test_a_tiff_cut_before_its_directory_is_refused_in_our_line_alone(tmp_path: Path) -> None:
    """Pillow's "UserWarning: Corrupt EXIF data. Expecting to read 2 bytes but only got 0." and its source line
    came before the refusal."""
    whole = tmp_path / "whole.tif"
    Image.fromarray(np.random.default_rng(1).integers(0, 255, (16, 16, 3), dtype=np.uint8)).save(
        whole, compression="tiff_deflate"
    )
    cut = tmp_path / "cut.tif"
    cut.write_bytes(whole.read_bytes()[:500])
    assert_one_line_error(run("centre", cut), "cut.tif: cannot read it as an image")


def test_a_webp_whose_data_end_early_is_no_video(tmp_path: Path) -> None:
    """A lossy WebP of 16 x 16 px whose header claims 4000 x 4000: libwebp refuses it, and it was then taken for a
    video ("is a video: its first frame is used"), FFmpeg decoding 16 megapixels of it in 2.7 s and 550 MB."""
    small = np.random.default_rng(1).integers(0, 255, (16, 16, 3), dtype=np.uint8)
    data = bytearray(cv2.imencode(".webp", small, [cv2.IMWRITE_WEBP_QUALITY, 90])[1].tobytes())
    start = data.find(b"\x9d\x01\x2a") + 3  # (the VP8 frame's start code, then its width and height)
    data[start : start + 4] = struct.pack("<HH", 4000, 4000)
    path = tmp_path / "x.webp"
    path.write_bytes(data)
    assert_one_line_error(run("centre", path), "x.webp: cannot read it as an image (a truncated or corrupt WebP)")


# ----------------------------------------------------------------------------- E3: the demo


def test_the_demo_where_its_disk_has_no_room_writes_nothing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """On a disk of 1 MB it wrote omni.png and landmarks.csv, then failed on table.npz ("No space left on
    device"); it writes about 41 MB."""
    no_room(monkeypatch, 1_000_000)
    out = tmp_path / "demo"
    result = run("demo", "-o", out)
    assert_one_line_error(result, "omni.png: no room for it: up to 48.0 MB to write, its disk has 1.0 MB free")
    assert not out.exists()


# ----------------------------------------------------------------------------- E4: a video as a rig's picture

LENS = 64  # px a side; an ideal equidistant lens of 190 deg fills it
RIG_CAMCHAIN = "\n".join(
    f"cam{k}:\n  camera_model: pinhole\n  intrinsics: [19.3, 19.3, 31.5, 31.5]\n  distortion_model: equidistant\n"
    f"  distortion_coeffs: [0.0, 0.0, 0.0, 0.0]\n  resolution: [{LENS}, {LENS}]\n"
    + ("  T_cn_cnm1:\n  - [-1, 0, 0, 0]\n  - [0, 1, 0, 0]\n  - [0, 0, -1, -0.02]\n  - [0, 0, 0, 1]\n" if k else "")
    for k in range(2)
)


@pytest.fixture(scope="module")
def dual(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder with a dual fisheye's camchain (camchain.yaml), its side-by-side rig (rig.npz), and a clip of its
    frames (dual.mp4, 128 x 64 px)."""
    folder = tmp_path_factory.mktemp("dual")
    (folder / "camchain.yaml").write_text(RIG_CAMCHAIN)
    result = run("import", folder / "camchain.yaml", "-o", folder / "rig.npz", "--side-by-side", "--fov", 190, "-q")
    assert result.exit_code == 0, result.output + result.stderr
    frames = np.random.default_rng(4).integers(0, 255, (2, LENS, 2 * LENS, 3), dtype=np.uint8)
    write_clip(folder / "dual.mp4", list(frames), 5)
    return folder


def test_a_rigs_view_of_a_video_says_it_is_one(dual: Path, tmp_path: Path) -> None:
    """It said "cannot read it as an image (unknown format or corrupt)"; a table's view says that ``panomap video``
    unwarps a video."""
    out = tmp_path / "pano.png"
    result = run("equirect", dual / "rig.npz", dual / "dual.mp4", "-o", out, "--size", "64x32")
    assert_one_line_error(result, "dual.mp4: it is a video: unwarp it with panomap video")
    assert not out.exists()


@pytest.mark.parametrize("command", ["import", "rig learn"])
def test_a_video_given_as_a_rigs_frame_gives_its_first_frame(
    dual: Path, tmp_path: Path, command: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``import CAMCHAIN --side-by-side --image VIDEO`` and ``rig learn RIG VIDEO`` said "unknown format or
    corrupt", where one camera's ``import --image``, ``centre`` and ``rig learn --side-by-side`` take its first
    frame."""
    taken: list[tuple[int, ...]] = []

    def stop(pictures: list[np.ndarray], *_: object, **__: object) -> None:
        taken.extend(np.shape(picture) for picture in pictures)
        raise SystemExit(3)

    if command == "import":
        monkeypatch.setattr("panomap.cli.rigs._circles_of_pictures", lambda c, i, pictures, *a: stop(pictures))
        args = ["import", dual / "camchain.yaml", "--side-by-side", "--fov", 190, "--image", dual / "dual.mp4"]
    else:
        monkeypatch.setattr("panomap.rig.overlap.learn_with_overlap", lambda rig, shots, **k: stop(shots))
        args = ["rig", "learn", dual / "rig.npz", dual / "dual.mp4"]
    result = run(*args, "-o", tmp_path / "out.npz", "-q")
    assert result.exit_code == 3, result.output + result.stderr
    assert taken == [(LENS, 2 * LENS, 3)] and result.stderr == ""  # (-q: no note that its first frame is used)


def test_a_rig_learned_from_one_shot_given_twice_is_refused(
    dual: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``rig learn RIG dual.jpg COPY`` (the same pixels saved again) counted each match twice: the demo's back
    lens went from "tilt within 0.805 deg ... not pinned" to "within 0.054 deg", pinned by nothing new."""
    monkeypatch.setattr("panomap.rig.overlap.learn_with_overlap", lambda *a, **k: pytest.fail("it learned"))
    frame = np.random.default_rng(5).integers(0, 255, (LENS, 2 * LENS, 3), dtype=np.uint8)
    cv2.imwrite(str(tmp_path / "a.png"), frame)
    cv2.imwrite(str(tmp_path / "b.bmp"), frame)
    out = tmp_path / "learned.npz"
    result = run("rig", "learn", dual / "rig.npz", tmp_path / "a.png", tmp_path / "b.bmp", "-o", out)
    assert_one_line_error(result, "b.bmp: the same pixels as shot 1: give each shot once")
    result = run("rig", "learn", dual / "rig.npz", tmp_path / "a.png", tmp_path / "a.png", "-o", out)
    assert_one_line_error(result, "are one picture (the same file): give each picture once", exit_code=2)
    assert not out.exists()


# ----------------------------------------------------------------------------- E5: a table too coarse in elevation


def test_the_rows_bound_is_what_a_table_read_between_its_elevations_gives() -> None:
    """A camera whose radius is r = a rho^2 (closed form): read linearly between entries h apart a table is a h^2 / 4
    off halfway, and 2 a h^2 off where its last row's extrapolation reaches the range's end: 2 a / N^2 for a range
    of 1 rad, within 1 px from N >= sqrt(2 a)."""
    import math

    from panomap.errors import PanomapError
    from panomap.table.table import check_table_rows

    a = 100.0

    def grid(size: tuple[int, int], elevation_range: tuple[float, float]) -> np.ndarray:
        m, n = size
        rho = elevation_range[0] + np.arange(n) * (elevation_range[1] - elevation_range[0]) / n
        theta = 2 * math.pi * np.arange(m) / m
        r = a * rho**2
        return np.stack([np.cos(theta)[:, None] * r, np.sin(theta)[:, None] * r], axis=-1)

    least = math.ceil(math.sqrt(2 * a))
    check_table_rows((8, least), (0.0, 1.0), grid)
    with pytest.raises(PanomapError, match=f"8x{least - 1}: between its {least - 1} elevations the views would be up "
                       f"to 1 px off: give N >= {least} "):  # fmt: skip
        check_table_rows((8, least - 1), (0.0, 1.0), grid)
    with pytest.raises(PanomapError, match="8x2: between its 2 elevations the views would be up to 50 px off"):
        check_table_rows((8, 2), (0.0, 1.0), grid)


def test_a_table_of_a_given_size_too_coarse_in_elevation_is_refused(tmp_path: Path) -> None:
    """``import --table-size 64x16`` was written, its views up to 27 px off the default table's (an equirect view:
    median 0.04 px); ``fit --size 56x2`` on the demo, up to 141 px off."""
    from test_hardening7 import ocam_file

    calibration = ocam_file(tmp_path / "calib_results.txt")
    out = tmp_path / "cam.npz"
    result = run("import", calibration, "-o", out, "--table-size", "64x16")
    assert_one_line_error(result, "table size 64x16: between its 16 elevations the views would be up to 28 px off: "
                          "give N >= 144 (within 1 px)")  # fmt: skip
    assert not out.exists()


# ----------------------------------------------------------------------------- E6: what came before a refusal


def test_an_imports_note_is_not_printed_before_its_refusal(tmp_path: Path) -> None:
    """The note naming what was read ("OpenCalib OCam intrinsic 'front_camera-intrinsic'") came on a line before
    the refusal of the table's size or of the image."""
    from test_interop_opencalib import intrinsic

    calibration = tmp_path / "front.json"
    calibration.write_text(json.dumps(intrinsic()))
    result = run("import", calibration, "-o", tmp_path / "cam.npz", "--table-size", "8x64")
    assert_one_line_error(result, "front.json: table size 8x64: between its 8 azimuths")


@pytest.mark.parametrize(
    ("kind", "given", "message"),
    [
        ("basalt", "opencalib", "not an OpenCalib intrinsic: its one object, value0, has no param"),
        ("ocam", "opencalib", "not an OpenCalib intrinsic: it holds one object (its sensor's), this one 27 objects"),
        ("opencalib", "gyroflow", "not a gyroflow lens profile (no fisheye_params or calib_dimension)"),
        ("basalt", "gyroflow", "not a gyroflow lens profile (no fisheye_params or calib_dimension)"),
    ],
)
def test_another_tools_json_given_as_opencalib_or_gyroflow_says_it_is_none(
    tmp_path: Path, kind: str, given: str, message: str
) -> None:
    """As OpenCalib: a Basalt calibration said "value0.param is missing", OCamCalib's JSON "an OpenCalib file holds
    one object (its sensor's), this one 27 objects"; as gyroflow, either said "fisheye_params is missing" (Basalt's
    reader, given another tool's file, says "not a Basalt calibration (no "value0" object)")."""
    from test_interop_opencalib import intrinsic

    data = {"value0": {"intrinsics": []}} if kind == "basalt" else {f"k{k}": k for k in range(27)}
    calibration = tmp_path / "cam.json"
    calibration.write_text(json.dumps(intrinsic() if kind == "opencalib" else data))
    result = run("import", calibration, "-o", tmp_path / "cam.npz", "--format", given)
    assert_one_line_error(result, f"cam.json: {message}")


def test_a_manifest_listing_an_input_twice_says_so(inputs: Path, tmp_path: Path) -> None:
    """It said "two outputs would be this file (omni.png and omni.png): put {stem} or {camera} in the template",
    of a template holding both."""
    manifest = tmp_path / "cams.csv"
    manifest.write_text("input,table,camera\n" + f"{inputs / 'omni.png'},{inputs / 'cam.npz'},c\n" * 2)
    result = run("batch", manifest, "-o", str(tmp_path / "out" / "{camera}_{stem}_{name}.png"), "--view",
                 "panorama:size=64x16", "--workers", 1, "--record", tmp_path / "record.jsonl")  # fmt: skip
    assert_one_line_error(result, "omni.png is listed twice for this output: list it once")
    assert not (tmp_path / "out").exists()


def test_a_perspective_view_with_no_angles_of_a_mirror_camera_imported_without_its_cut_off_looks_off_its_axis(
    tmp_path: Path,
) -> None:
    """``import --mirror`` with no picture leaves the cut-off disc (the camera's own reflection) in the table:
    ``perspective`` with no angles looked along the axis, at the camera itself ("100% of pixels with a source" on
    the shared VMR mirror). It turns off the axis now by the middle of the angles the table sees, as with a cut-off:
    level, to the pitch halfway along the table's elevations."""
    from panomap.table.file import load_table
    from panomap.views.perspective import default_direction
    from test_hardening7 import ocam_file

    out = tmp_path / "mirror.npz"
    assert run("import", ocam_file(tmp_path / "calib_results.txt"), "-o", out, "--mirror", "-q").exit_code == 0
    table = load_table(out)
    low, high = table.elevation_range
    assert low == pytest.approx(-np.pi / 2)  # (no cut-off: the table reaches the axis)
    _, pitch = default_direction(table)
    assert pitch == pytest.approx((low + high) / 2, abs=1e-9)


def test_a_camera_name_given_beside_a_manifest_is_refused(inputs: Path, tmp_path: Path) -> None:
    """``batch cams.csv --camera x`` ran, every output under the manifest's camera names: --camera silently
    ignored (it names the camera without a manifest), as --table beside a manifest is not."""
    manifest = tmp_path / "cams.csv"
    manifest.write_text(f"input,table,camera\n{inputs / 'omni.png'},{inputs / 'cam.npz'},c\n")
    result = run("batch", manifest, "--camera", "x", "-o", str(tmp_path / "out" / "{camera}_{name}.png"), "--view",
                 "panorama:size=64x16", "--workers", 1, "--record", tmp_path / "record.jsonl")  # fmt: skip
    assert_one_line_error(result, "cams.csv names each input's camera (or takes its table's stem): give no --camera",
                          exit_code=2)  # fmt: skip
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("command", [["demo", "-o", ""], ["learn", "omni.png", "--dir", ""]])
def test_an_empty_folder_name_is_refused(command: list[str], monkeypatch: pytest.MonkeyPatch) -> None:
    """``demo -o ''`` wrote its 41 MB into the current folder, unsaid (the other commands' ``-o ''`` is "." and
    refused as a folder)."""
    monkeypatch.setattr("panomap.cli.demo.run_demo", lambda *a, **k: pytest.fail("the demo ran"))
    result = run(*command)
    assert_one_line_error(result, "an empty folder name: give one ('.' for the current folder)", exit_code=2)
