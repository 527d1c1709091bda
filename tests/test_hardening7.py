"""Hardening 7: what hardening 6 left, and the command line fuzzed where it changed last; each fault pinned here.

A picture whose header claims more pixels than its bytes hold (D1); outputs their disk has no room for, found
before the work (D2); a pixel for azimuth 0 outside the scene, refused before the fit (D3); a view too wide for the
video encoder, refused once by ``batch`` (D4).
"""

from __future__ import annotations

import shutil
import struct
import zlib
from pathlib import Path

import cv2
import numpy as np
import pytest

from panomap.errors import PanomapError

from helpers import assert_one_line_error, hyperbolic_inputs, run, write_clip

SIZE = (240, 240)


@pytest.fixture(scope="module")
def inputs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder with a table fitted to a simulated hyperbolic camera (cam.npz), its rig of two (rig.npz) and an
    image of its size (omni.png)."""
    folder = tmp_path_factory.mktemp("hardening7")
    hyperbolic_inputs(folder, SIZE, (121.3, 118.2), 30, "cam.npz")
    result = run("rig", "make", folder / "cam.npz", folder / "cam.npz", "--name", "a", "--name", "b",
                 "-o", folder / "rig.npz")  # fmt: skip
    assert result.exit_code == 0, result.output + result.stderr
    return folder


def no_room(monkeypatch: pytest.MonkeyPatch, free: int) -> None:
    """Every disk has ``free`` bytes free."""
    monkeypatch.setattr("panomap.files.shutil.disk_usage", lambda _path: shutil._ntuple_diskusage(10**12, 0, free))


# ----------------------------------------------------------------------------- D1: a header's claim, held to its bytes


def claiming(path: Path, size: tuple[int, int], grey: bool = False) -> Path:
    """A JPEG of 16 x 16 px whose frame header is rewritten to claim ``size`` (width, height): its data end long
    before the pixels claimed do."""
    small = np.random.default_rng(1).integers(0, 255, (16, 16) if grey else (16, 16, 3), dtype=np.uint8)
    data = bytearray(cv2.imencode(".jpg", small)[1].tobytes())
    frame = data.find(b"\xff\xc0")
    data[frame + 5 : frame + 9] = struct.pack(">HH", size[1], size[0])
    path.write_bytes(data)
    return path


def png_claiming(path: Path, size: tuple[int, int]) -> Path:
    """A PNG whose header claims ``size`` (RGB, 8-bit) over an image data stream of 2000 zero bytes."""

    def chunk(kind: bytes, body: bytes) -> bytes:
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))

    header = struct.pack(">IIBBBBB", *size, 8, 2, 0, 0, 0)
    body = chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(bytes(2000))) + chunk(b"IEND", b"")
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + body)
    return path


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda p: claiming(p / "x.jpg", (4000, 4000)), "a truncated or corrupt JPEG: its header claims 4000 x 4000 "
         "px, which take at least 31 kB, not"),
        (lambda p: claiming(p / "x.jpg", (4000, 3000), grey=True), "a truncated or corrupt JPEG: its header claims "
         "4000 x 3000 px, which take at least 23 kB, not"),
        (lambda p: png_claiming(p / "x.png", (4000, 4000)), "a truncated or corrupt PNG: its header claims 4000 x 4000 "
         "px, which take at least 47 kB, not 80 bytes"),
    ],
)  # fmt: skip
def test_an_image_whose_header_claims_more_than_its_bytes_hold_is_refused_before_decoding(
    tmp_path: Path, capfd: pytest.CaptureFixture[str], make: object, message: str
) -> None:
    """libjpeg filled what the file lacked with grey: a JPEG of 629 bytes claiming 16000 x 16000 px decoded to
    256 megapixels in 6 s (2 GB), then "no image circle found" (and libjpeg's own "Corrupt JPEG data" line)."""
    path = make(tmp_path)  # type: ignore[operator]
    assert_one_line_error(run("centre", path), f"{path.name}: cannot read it as an image ({message}")
    assert capfd.readouterr().err == ""


def test_a_jpeg_whose_data_end_early_is_refused_in_our_line_alone(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    """Within the bound, the decoder still filled the rest with grey: libjpeg wrote "Corrupt JPEG data: premature
    end of data segment" on a line of its own, and ``centre`` went on with the grey picture."""
    path = claiming(tmp_path / "short.jpg", (640, 480))
    assert_one_line_error(run("centre", path), "short.jpg: cannot read it as an image (a truncated or corrupt file: "
                          "premature end of data segment)")  # fmt: skip
    assert capfd.readouterr().err == ""


def test_a_png_whose_data_end_early_says_why(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    """libpng's "libpng error: Not enough image data" went to the terminal beside our line."""
    path = png_claiming(tmp_path / "short.png", (64, 64))
    assert_one_line_error(run("centre", path), "short.png: cannot read it as an image", "Not enough image data")
    assert capfd.readouterr().err == ""


@pytest.mark.parametrize("suffix", [".png", ".jpg"])
def test_the_bound_holds_for_the_most_compressible_pictures_their_encoders_make(tmp_path: Path, suffix: str) -> None:
    """A flat picture, each encoder at its strongest: its file is over the bound (the bound is the format's
    least, never a guess at pictures' usual size), and it is read."""
    from panomap.io.image_bounds import least_file_bytes
    from panomap.io.images import read_image

    flat = np.full((3000, 4000), 128, np.uint8)
    path = tmp_path / f"flat{suffix}"
    options = [cv2.IMWRITE_PNG_COMPRESSION, 9] if suffix == ".png" else [cv2.IMWRITE_JPEG_QUALITY, 1]
    assert cv2.imwrite(str(path), flat, options)
    kind, least = least_file_bytes(path, (4000, 3000))  # type: ignore[misc]
    assert kind == suffix[1:].upper().replace("JPG", "JPEG") and least < path.stat().st_size, (least, path.stat())
    assert read_image(path).shape == (3000, 4000)


def test_an_image_larger_decoded_than_the_memory_available_is_refused(
    inputs: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr("panomap.io.images.available_memory", lambda: 100_000)
    result = run("centre", inputs / "omni.png")
    assert_one_line_error(result, "omni.png: the image is 240 x 240: decoded, it takes 173 kB of memory, more than "
                          "the 100 kB available")  # fmt: skip


# ----------------------------------------------------------------------------- D2: room on the disk, before the work


def test_a_view_its_disk_has_no_room_for_is_refused_before_the_work(
    inputs: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The image (its pixels, uncompressed, at most) was found too large for its disk when it was written."""
    no_room(monkeypatch, 50_000)
    out = tmp_path / "p.png"
    result = run("panorama", inputs / "cam.npz", inputs / "omni.png", "-o", out, "--size", "200x100")
    assert_one_line_error(result, "p.png: no room for it: up to 64 kB to write, its disk has 50 kB free")
    result = run("equirect", inputs / "rig.npz", inputs / "omni.png", inputs / "omni.png", "-o", out,
                 "--size", "200x100")  # fmt: skip
    assert_one_line_error(result, "p.png: no room for it: up to 64 kB to write, its disk has 50 kB free")
    assert list(tmp_path.iterdir()) == []
    no_room(monkeypatch, 70_000)
    result = run("panorama", inputs / "cam.npz", inputs / "omni.png", "-o", out, "--size", "200x100", "-q")
    assert result.exit_code == 0 and out.stat().st_size < 64_000, result.stderr


def test_a_table_of_a_size_the_fit_chooses_is_refused_before_the_fit(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Its size was only known after the fit: 2 pi R x R entries at most for a picture of half diagonal R."""
    marks = tmp_path / "marks.csv"
    marks.write_text("u,v,X,Y,Z\n" + "".join(f"{100 + k},{120 + k},{k},1,0\n" for k in range(6)))
    monkeypatch.setattr("panomap.cli.calibrate.calibrate_camera", lambda *a, **k: pytest.fail("the fit ran"))
    no_room(monkeypatch, 1_000_000)
    result = run("fit", marks, "-o", tmp_path / "cam.npz", "--camera", 0, 0, 2, "--centre", 120, 120,
                 "--image-size", "240x240")  # fmt: skip
    assert_one_line_error(result, "cam.npz: no room for it: up to 1.5 MB to write, its disk has 1.0 MB free")
    assert sorted(path.name for path in tmp_path.iterdir()) == ["marks.csv"]


@pytest.mark.parametrize("command", ["level", "rig learn", "rig place"])
def test_a_table_or_rig_made_from_another_is_refused_where_its_disk_has_no_room_for_its_size(
    inputs: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, command: str
) -> None:
    """``level`` read its pictures and found their lines, ``rig learn`` and ``rig place`` did their work, before
    a full disk was found."""
    no_room(monkeypatch, 5_000)
    out = tmp_path / "out.npz"
    if command == "level":
        args, made_from = ["level", inputs / "cam.npz", inputs / "omni.png"], "cam.npz"
    elif command == "rig learn":
        args, made_from = ["rig", "learn", inputs / "rig.npz", inputs / "omni.png", inputs / "omni.png"], "rig.npz"
    else:
        marks = tmp_path / "floor.csv"
        marks.write_text("u,v,X,Y,Z\n1,2,3,4,0\n")
        args, made_from = ["rig", "place", inputs / "rig.npz", marks, marks], "rig.npz"
    result = run(*args, "-o", out)
    size = (inputs / made_from).stat().st_size
    shown = f"{size / 1e6:.1f} MB" if size >= 1e6 else f"{size / 1e3:.0f} kB"
    assert_one_line_error(result, f"out.npz: no room for it: {shown} to write, its disk has 5 kB free")
    assert not out.exists()


# ----------------------------------------------------------------------------- D3: azimuth 0, before the fit


def test_a_pixel_for_azimuth_zero_outside_the_scene_is_refused_before_the_fit(
    inputs: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """It was refused after the fit (seconds on a real picture), at the fitted centre."""
    monkeypatch.setattr("panomap.calibrate.pictures.find_arcs", lambda *a, **k: pytest.fail("the search ran"))
    out = tmp_path / "cam.npz"
    result = run("fit", "--image", inputs / "omni.png", "-o", out, "--azimuth-zero", 120, 119)
    assert_one_line_error(result, "omni.png: the pixel given for azimuth 0, (120, 119)", "give a pixel of the scene")
    assert not out.exists()


# ----------------------------------------------------------------------------- D4: batch, a view too wide, once


def test_batch_refuses_a_view_too_wide_for_the_encoder_once_before_the_cluster(inputs: Path, tmp_path: Path) -> None:
    """Each video's task was refused on the cluster, one line each, then the summary."""
    clip = tmp_path / "clip.mp4"
    write_clip(clip, [cv2.imread(str(inputs / "omni.png"))] * 2, 5)
    result = run("batch", "--workers", "1", "--view", "equirect:size=16386x64", "--view", "panorama:size=64x16",
                 clip, "--table", inputs / "cam.npz", "-o", f"{tmp_path}/{{stem}}_{{name}}.mp4",
                 "--record", tmp_path / "record.jsonl")  # fmt: skip
    assert_one_line_error(result, "'--view': equirect: the video encoder libx264 cannot encode frames of 16386 x 64",
                          "give the view a smaller size", exit_code=2)  # fmt: skip
    assert sorted(path.name for path in tmp_path.iterdir()) == ["clip.mp4"]


# ----------------------------------------------------------------------------- D5: the command line fuzzed


def test_a_dual_fisheyes_frame_given_twice_is_refused_before_the_work(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``rig learn --side-by-side`` learned from the one frame twice (25 s on the shared Insta360 frame), then
    refused it as pinning neither lens; ``fit`` and ``level`` refuse a picture given twice."""
    monkeypatch.setattr("panomap.calibrate.dual_fisheye.learn_dual_fisheye", lambda *a, **k: pytest.fail("it ran"))
    frame = tmp_path / "frame.png"
    cv2.imwrite(str(frame), np.zeros((20, 40, 3), np.uint8))
    shutil.copy(frame, tmp_path / "copy.png")
    for second, how in ((frame, "the same file"), (tmp_path / "copy.png", "the same bytes")):
        result = run("rig", "learn", "--side-by-side", frame, second, "-o", tmp_path / "rig.npz")
        assert_one_line_error(result, f"are one frame ({how}): give each frame once", exit_code=2)
    assert not (tmp_path / "rig.npz").exists()


def test_a_dual_fisheyes_frame_of_odd_width_is_named(tmp_path: Path) -> None:
    """ "a side-by-side frame 41 px wide" named no file among the frames."""
    cv2.imwrite(str(tmp_path / "even.png"), np.zeros((20, 40, 3), np.uint8))
    cv2.imwrite(str(tmp_path / "odd.png"), np.zeros((20, 41, 3), np.uint8))
    result = run(
        "rig", "learn", "--side-by-side", tmp_path / "even.png", tmp_path / "odd.png", "-o", tmp_path / "r.npz"
    )
    assert_one_line_error(result, "odd.png: a side-by-side frame 41 px wide: two lenses of one size make it even")


def test_a_dual_fisheyes_video_gives_its_frame_as_the_other_commands_take_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A video said "cannot read it as an image (unknown format or corrupt)"; ``centre``, ``import --image`` and
    ``level`` take its first frame (or the one at --frame-time)."""
    taken: list[tuple[int, ...]] = []

    def learned(frames: list[np.ndarray], **_: object) -> None:
        taken.extend(frame.shape for frame in frames)
        raise PanomapError("stopped here")

    monkeypatch.setattr("panomap.calibrate.dual_fisheye.learn_dual_fisheye", learned)
    clip = tmp_path / "dual.mp4"
    write_clip(clip, [np.full((64, 128, 3), 100, np.uint8)] * 2, 5)
    result = run("rig", "learn", "--side-by-side", clip, "-o", tmp_path / "r.npz", "-q")
    assert_one_line_error(result, "stopped here")  # (-q: no note that the video's first frame is used)
    assert taken == [(64, 128, 3)]


def test_a_picture_read_as_text_is_said_to_be_no_text(inputs: Path, tmp_path: Path) -> None:
    """``rig place RIG omni.png omni.png`` said "cannot read it (UnicodeDecodeError: 'utf-8' codec can't decode
    byte 0x89 in position 0: invalid start byte)"."""
    out = tmp_path / "placed.npz"
    result = run("rig", "place", inputs / "rig.npz", inputs / "omni.png", inputs / "omni.png", "-o", out)
    assert_one_line_error(
        result, "omni.png: not a text file (byte 0x89 at 0 is not UTF-8): a picture or another binary"
    )
    assert "Error" not in result.stderr and not out.exists()


def test_over_sixteen_tables_are_refused_before_they_are_loaded(inputs: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Seventeen tables were loaded (10 MB each from a demo) before the rig refused them."""
    monkeypatch.setattr("panomap.table.file.load_table", lambda *a, **k: pytest.fail("a table was loaded"))
    out = inputs / "r17.npz"
    names = [arg for k in range(17) for arg in ("--name", f"c{k}")]
    result = run("rig", "make", *[inputs / "cam.npz"] * 17, *names, "-o", out)
    assert_one_line_error(result, "'TABLES...': a rig has 1 to 16 cameras, not 17", exit_code=2)
    assert not out.exists()


def ocam_file(path: Path) -> Path:
    """An OCamCalib calib_results.txt of a 640 x 480 fisheye (the polynomial of a 160 px per radian lens)."""
    path.write_text(
        "#polynomial coefficients for the DIRECT mapping function (ocam_model.ss in MATLAB). These are used by "
        "cam2world\n\n4 -160.0 0.0 0.0006 -0.000001\n\n#polynomial coefficients for the inverse mapping function "
        "(ocam_model.invpol in MATLAB). These are used by world2cam\n\n5 230.0 140.0 10.0 20.0 5.0\n\n"
        '#center: "row" and "column", starting from 0 (C convention)\n\n240.0 320.0\n\n#affine parameters '
        '"c", "d", "e"\n\n1.0 0.0 0.0\n\n#image size: "height" and "width"\n\n480 640\n'
    )
    return path


@pytest.mark.parametrize(("size", "message", "code"), [
    ("1x1", "'--table-size 1x1: a table needs M >= 4 and N >= 2", 2),
    ("4x2", "table size 4x2: between its 4 azimuths the views would be up to", 1),
])  # fmt: skip
def test_an_imported_table_too_small_or_too_coarse_is_refused(tmp_path: Path, size: str, message: str,
                                                              code: int) -> None:  # fmt: skip
    """1x1 was refused after the calibration was read, as the calibration's fault (exit 1); 4x2 was written: its
    perspective views 25 px (median) to 48 px off those of the default table, silently."""
    calibration = ocam_file(tmp_path / "calib_results.txt")
    out = tmp_path / "cam.npz"
    assert run("import", calibration, "-o", tmp_path / "fine.npz", "--table-size", "64x160", "-q").exit_code == 0
    result = run("import", calibration, "-o", out, "--table-size", size)
    assert_one_line_error(result, message.lstrip("'"), exit_code=code)
    assert not out.exists()


def test_the_chords_bound_is_what_a_table_read_between_its_azimuths_gives(inputs: Path) -> None:
    """Between two azimuths a table reads the chord between its entries: at mid-azimuth r cos(pi / M) from the
    centre (closed form), r (1 - cos(pi / M)) inside the circle: the sagitta the refusal bounds by r (pi / M)^2 / 2.
    Here M = 712, r = 112.7 px: the sagitta is 1.1e-3 px, the reading within 2.3e-5 px of the chord (measured), so
    1e-4 px tells the chord from the circle."""
    import math

    from panomap.table.file import load_table
    from panomap.table.table import MAX_CHORD_PX, check_table_chords

    table = load_table(inputs / "cam.npz")
    m = table.size[0]
    rho = table.elevation_range[1]
    theta = (np.arange(m) + 0.5) * 2 * math.pi / m
    edge = table.sample(np.arange(m) * 2 * math.pi / m, np.full(m, rho)).astype(np.float64)
    middle = table.sample(theta, np.full(m, rho)).astype(np.float64)
    centre = np.asarray(table.model.centre)
    r = np.hypot(*(edge - centre).T)
    read = np.hypot(*(middle - centre).T)
    np.testing.assert_allclose(read, r * math.cos(math.pi / m), rtol=0, atol=1e-4)
    sagitta = float(r.max()) * (math.pi / m) ** 2 / 2
    assert abs(float(np.max(r - read)) - sagitta) < 1e-4  # the bound is the worst sagitta read (1.12e-3 px here)
    check_table_chords(table.size, float(r.max()))  # (its default size: far within)
    least = math.ceil(math.pi * math.sqrt(100.0 / (2 * MAX_CHORD_PX)))
    check_table_chords((least, 2), 100.0)
    with pytest.raises(PanomapError, match=f"give M >= {least}"):
        check_table_chords((least - 1, 2), 100.0)


def test_the_note_that_a_videos_frame_is_used_is_silenced_by_q(inputs: Path, tmp_path: Path) -> None:
    """``-q`` prints nothing but the result, warnings and errors: the note was printed beside the error."""
    clip = tmp_path / "clip.mp4"
    write_clip(clip, [cv2.imread(str(inputs / "omni.png"))] * 2, 5)
    result = run("level", inputs / "cam.npz", clip, "-o", tmp_path / "level.npz", "-q")
    assert result.exit_code == 1 and "note" not in result.stderr, result.stderr
    assert len(result.stderr.strip().splitlines()) == 1, result.stderr


def test_a_cutoff_radius_not_below_the_outer_one_is_refused_before_the_work(tmp_path: Path) -> None:
    """``fit --cutoff-radius 300 --outer-radius 200`` fitted, then said "no radial model covers the annulus from
    these landmarks" (blaming them); ``import --image`` read and searched the picture first (exit 1)."""
    from panomap.calibrate.landmarks.pairs import read_landmarks
    from panomap.calibrate.landmarks.pipeline import calibrate_camera

    marks = tmp_path / "marks.csv"
    marks.write_text("u,v,X,Y,Z\n" + "".join(f"{100 + 7 * k},{120 + 3 * k},{k},1,0\n" for k in range(8)))
    with pytest.raises(PanomapError, match=r"the cut-off radius \(300 px\) must be >= 0 and below the outer radius"):
        calibrate_camera(read_landmarks(marks), (0, 0, 2), centre=(120, 120), cutoff_radius=300, outer_radius=200)
    out = tmp_path / "cam.npz"
    radii = ["--cutoff-radius", 300, "--outer-radius", 200]
    for args in (["fit", marks, "--camera", 0, 0, 2, "--centre", 120, 120], ["import", ocam_file(tmp_path / "c.txt")]):
        result = run(*args, "-o", out, *radii)
        assert_one_line_error(result, "'--cutoff-radius': 300 px: the cut-off radius must be below the outer radius "
                              "(200 px)", exit_code=2)  # fmt: skip
    assert not out.exists()


@pytest.mark.parametrize(
    ("name", "size", "message"),
    [
        ("wide.webp", "17000x10", "an image of 17000 x 10 px: WEBP holds at most 16383 px a side (write .png)"),
        ("noname", "100x10", "cannot write an image in the format (no suffix): name it .png or .jpg"),
        ("view.npy", "100x10", "cannot write an image in the format .npy: name it .png or .jpg"),
    ],
)
def test_an_output_image_its_format_cannot_hold_is_refused_before_the_work(
    inputs: Path, tmp_path: Path, capfd: pytest.CaptureFixture[str], name: str, size: str, message: str
) -> None:
    """They were refused once the view was made; a WebP over 16383 px a side with OpenCV's own two [ERROR] lines
    (its log) before ours."""
    out = tmp_path / name
    for args in (["panorama", inputs / "cam.npz", inputs / "omni.png"],
                 ["equirect", inputs / "rig.npz", inputs / "omni.png", inputs / "omni.png"]):  # fmt: skip
        result = run(*args, "-o", out, "--size", size)
        assert_one_line_error(result, "'-o'", f"{name}: {message}", exit_code=2)
    assert capfd.readouterr().err == "" and list(tmp_path.iterdir()) == []
    from panomap.io.images import write_image

    with pytest.raises(PanomapError, match="WEBP holds at most 16383 px a side"):  # (the library's own writer)
        write_image(tmp_path / "wide.webp", np.zeros((2, 16384), np.uint8))
    assert capfd.readouterr().err == ""


def test_a_folder_of_videos_given_as_pictures_says_what_it_holds(tmp_path: Path) -> None:
    """``fit --image FOLDER`` of videos said only "the folder holds no image" (``--video`` takes them)."""
    (tmp_path / "clips").mkdir()
    (tmp_path / "clips" / "a.mp4").write_bytes(b"")
    (tmp_path / "clips" / "notes.txt").write_text("x")
    result = run("fit", "--image", tmp_path / "clips", "-o", tmp_path / "cam.npz")
    assert_one_line_error(result, "clips: the folder holds no image (it holds videos)", exit_code=2)


def test_a_rig_view_larger_than_the_memory_available_is_refused_before_the_work(
    inputs: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A rig's view takes memory for each camera (75 bytes a pixel a camera, measured): an equirect of 32000 x
    1562 px from 16 cameras needs some 60 GB; it was found by the system's OOM killer, after the work."""
    from panomap.rig.blend import rig_view_bytes

    assert rig_view_bytes((32000, 1562), 16) > 60e9
    monkeypatch.setattr("panomap.io.image_bounds.available_memory", lambda: 50_000_000)
    monkeypatch.setattr("panomap.cli.rigs.camera_maps", lambda *a, **k: pytest.fail("the maps were made"))
    out = tmp_path / "eq.png"
    result = run("equirect", inputs / "rig.npz", inputs / "omni.png", inputs / "omni.png", "-o", out, "--size",
                 "1000x500")  # fmt: skip
    assert_one_line_error(result, "a view of 1000 x 500 px of 2 cameras needs about 95 MB of memory, more than the "
                          "50 MB available: make it smaller")  # fmt: skip
    assert not out.exists()
