"""The Python API hardened the way a scikit-image or OpenCV user calls it.

Each test holds faults the round found (about 420 calls tried over every name in ``panomap.__all__``; the faults
are summed up in CHANGELOG.md): before, the call raised NumPy's, OpenCV's or Python's own error from deep inside
(``cv2.error``, ``AttributeError``, ``ValueError: too many values to unpack``), or returned a wrong result
silently (a size of 64.7 cut to 64, a text fill taken, a table from 2 landmarks given 3 times each). Now
each is a :class:`panomap.PanomapError` (or a ``TypeError`` for a wrong type) of one line naming the argument,
raised before any work is done, or the right result.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

import panomap
from panomap.simulate import standard_cameras

from helpers import learn_table, spread_landmarks

SIZE = (160, 160)
POSITION = (0.3, -0.2, 2.5)
FRAME = np.random.default_rng(63).integers(0, 256, (SIZE[1], SIZE[0], 3), dtype=np.uint8)
VIEW = panomap.PerspectiveView(yaw_rad=1.0, pitch_rad=-0.6, fov_rad=1.4, size=(24, 16))


@pytest.fixture(scope="module")
def chain() -> tuple[Any, Any, Any]:
    camera = standard_cameras(SIZE, centre=(80.4, 79.1))["hyperbolic"]
    marks = spread_landmarks(camera, POSITION, 30, np.random.default_rng(5))
    table, fit = learn_table(camera, POSITION, marks, SIZE, table_size=(64, 48))
    return marks, fit, table


def refused(call: Any, kind: type[Exception], *words: str) -> str:
    """The one-line message of the ``kind`` ``call`` raises, holding each of ``words``."""
    with pytest.raises(kind) as caught:
        call()
    message = str(caught.value)
    assert "\n" not in message and all(word in message for word in words), message
    assert "--" not in message and "cv2" not in message, message
    return message


# Remapper: its map, source size, fill and out.


def test_a_remapper_refuses_a_map_it_cannot_use() -> None:
    refused(lambda: panomap.Remapper(np.zeros((0, 4, 2), np.float32)), panomap.PanomapError, "map", "one pixel")
    refused(lambda: panomap.Remapper(np.array([[["a", "b"]]])), TypeError, "map", "real numbers")
    refused(lambda: panomap.Remapper(np.zeros((4, 4, 2)), "640x480"), TypeError, "source size")
    refused(lambda: panomap.Remapper(np.zeros((4, 4, 2)), (-1, 5)), panomap.PanomapError, "source size", "positive")


def test_a_fill_that_does_not_fit_the_frame_is_refused_not_wrapped() -> None:
    holes = np.full((4, 4, 2), np.nan, np.float32)
    refused(lambda: panomap.Remapper(holes, fill="black"), TypeError, "fill")
    for fill in (300, -1, math.nan):
        refused(lambda fill=fill: panomap.Remapper(holes, fill=fill)(FRAME), panomap.PanomapError, "fill", "uint8")
    refused(lambda: panomap.Remapper(holes, fill=(1.0, 2.0))(FRAME), panomap.PanomapError, "fill", "3 channels")
    # What fits is used as given: a list per channel, 65535 in a 16-bit frame, NaN in a float one.
    assert panomap.Remapper(holes, fill=[1, 2, 3])(FRAME)[0, 0].tolist() == [1, 2, 3]
    assert panomap.Remapper(holes, fill=65535)(FRAME.astype(np.uint16))[0, 0].tolist() == [65535] * 3
    assert np.isnan(panomap.Remapper(holes, fill=math.nan)(FRAME.astype(np.float32))).all()


def test_out_is_checked_and_any_layout_is_written(chain) -> None:
    _, _, table = chain
    remap = VIEW.remapper(table)
    plain = remap(FRAME)
    refused(lambda: remap(FRAME, out=[[0]]), TypeError, "output")
    locked = np.zeros_like(plain)
    locked.setflags(write=False)
    refused(lambda: remap(FRAME, out=locked), panomap.PanomapError, "read-only")
    fortran = np.asfortranarray(np.zeros_like(plain))  # (OpenCV cannot write this layout: written through a copy)
    assert remap(FRAME, out=fortran) is fortran
    np.testing.assert_array_equal(fortran, plain)


# Views: sizes and ranges.


@pytest.mark.parametrize(
    ("size", "kind", "words"),
    [
        ("64x48", TypeError, ("size", "2 numbers")),
        ((64, 48, 3), panomap.PanomapError, ("size", "2 numbers")),
        ((math.nan, 48), panomap.PanomapError, ("size", "finite")),
        ((64.7, 48.2), panomap.PanomapError, ("size", "whole numbers")),  # (was cut to 64 x 48)
        ((True, True), panomap.PanomapError, ("size",)),  # (was 1 x 1)
    ],
)
def test_a_view_size_that_is_no_two_whole_numbers_is_refused(size: Any, kind: type, words: tuple[str, ...]) -> None:
    refused(lambda: panomap.PerspectiveView(size=size), kind, *words)
    refused(lambda: panomap.GenericPanorama(size=size), kind, *words)
    assert panomap.PerspectiveView(size=(64.0, np.int64(48))).size == (64, 48)


def test_view_numbers_are_named_and_degrees_for_radians_are_told() -> None:
    refused(lambda: panomap.PerspectiveView(yaw_rad="30"), TypeError, "yaw_rad")
    refused(lambda: panomap.PerspectiveView(yaw_rad=np.array([1.0, 2.0])), TypeError, "yaw_rad")
    refused(lambda: panomap.FloorView(0.0, (0.0, 1.0, 2.0), (0.0, 5.0), (60, 50)), panomap.PanomapError, "x range")
    refused(lambda: panomap.FloorView(0.0, "0:6", (0.0, 5.0), (60, 50)), TypeError, "x range")
    refused(lambda: panomap.PerspectiveView(fov_rad=100), panomap.PanomapError, "math.radians(100)")
    refused(lambda: panomap.PerspectiveView(pitch_rad=-30), panomap.PanomapError, "math.radians(-30)")
    # A yaw of 270 is legal (it wraps); a spec's degrees are no radians typed as degrees.
    assert panomap.PerspectiveView(yaw_rad=270, pitch_rad=0).yaw_rad == 270
    message = refused(lambda: panomap.parse_view_spec("perspective:fov=400"), panomap.PanomapError, "400 deg")
    assert "math.radians" not in message


def test_maps_need_a_table_and_a_view(chain) -> None:
    _, _, table = chain
    rig = panomap.CameraRig((table, table), ("cam0", "cam1"))
    refused(lambda: panomap.build_map(table, None), TypeError, "the view")
    refused(lambda: panomap.build_map("cam.npz", VIEW), TypeError, "the table", "load_table")
    refused(lambda: VIEW.remapper(rig), TypeError, "rig.tables[k]", "camera_maps")
    refused(lambda: panomap.orient_table(rig, 0.0, 0.0, 0.0), TypeError, "rig.tables[k]")
    refused(lambda: panomap.orient_table(table, "0", 0.0, 0.0), TypeError, "yaw_rad")
    refused(lambda: panomap.camera_maps(table, VIEW), TypeError, "the rig", "build_map")
    refused(lambda: panomap.camera_maps(rig, None), TypeError, "the view")
    refused(lambda: panomap.camera_maps(rig, VIEW, threads=0), panomap.PanomapError, "threads")
    maps = panomap.camera_maps(rig, VIEW)
    refused(lambda: panomap.RigRemapper(rig, maps[:1]), panomap.PanomapError, "one map per camera")
    refused(lambda: panomap.RigRemapper(rig, [maps[0], maps[1][:4]]), panomap.PanomapError, "one shape")
    refused(lambda: panomap.parse_view_spec(VIEW), TypeError, "view spec")


# Pixels and points.


def test_unproject_and_project_check_their_shape_and_type(chain) -> None:
    _, _, table = chain
    refused(lambda: table.unproject("60,41"), TypeError, "pixels")
    refused(lambda: table.unproject([[1.0], [1.0, 2.0]]), panomap.PanomapError, "pixels", "rows")
    refused(lambda: table.project([[1.0, 2.0]]), panomap.PanomapError, "points", "(..., 3)")
    refused(lambda: table.project("1,2,3"), TypeError, "points")
    refused(lambda: table.project(None), TypeError, "points")  # (was NaN, NaN)
    # One pixel as (2,) is one pixel; NaN and pixels off the image are NaN out (documented in docs/python.md).
    theta, rho = table.unproject([60.0, 41.0])
    assert theta.shape == () and np.isfinite(theta) and np.isfinite(rho)
    off = table.unproject([[math.nan, 41.0], [-5.0, 41.0], [1e12, 1e12]])
    assert np.isnan(off[0]).all() and np.isnan(off[1]).all()


# Calibrating.


def test_repeated_landmarks_count_once(chain) -> None:
    marks, _, _ = chain
    picked = np.array([0, 1, 0, 1, 0, 1])  # (before: a camera fitted to 2 points, 3e-13 px RMS, NaN in its table)
    twice = panomap.Landmarks(marks.pixels[picked], marks.world[picked], tuple(np.asarray(marks.names)[picked]))
    refused(
        lambda: panomap.calibrate_camera(twice, POSITION, centre=(80.4, 79.1), image_size=SIZE),
        panomap.PanomapError,
        "only 2 distinct landmarks among 6",
    )


def test_sizes_given_to_calibrate_are_whole_numbers(chain) -> None:
    marks, fit, _ = chain
    calibrate = panomap.calibrate_camera
    refused(lambda: calibrate(marks, POSITION, centre=(80, 79), image_size="160x160"), TypeError, "image size")
    refused(lambda: calibrate(marks, POSITION, centre=(80, 79), image_size=(160.5, 160)), panomap.PanomapError, "whole")
    refused(lambda: panomap.create_table(fit, size="64x48"), TypeError, "table size")
    refused(lambda: panomap.create_table(fit, size=(64.5, 48)), panomap.PanomapError, "table size", "whole")
    refused(lambda: panomap.create_table("fit"), TypeError, "the fit", "fit_camera")
    refused(lambda: panomap.import_calibration("cam.yaml", tilt_rad=(0.1, 0.2, 0.3)), panomap.PanomapError, "tilt_rad")


def test_landmarks_of_the_wrong_shape_or_type_are_refused() -> None:
    refused(lambda: panomap.Landmarks("1,2", np.ones((1, 3)), ("a",)), TypeError, "pixels")
    refused(lambda: panomap.Landmarks(np.ones((5, 2)), np.ones((5, 2)), ("a",) * 5), panomap.PanomapError, "world")
    refused(lambda: panomap.Landmarks(np.ones((5, 2)), np.ones((5, 3)), "abcde"), TypeError, "names")


def test_learning_options_are_checked_before_the_pictures_are_searched() -> None:
    learn = panomap.learn_from_images
    black = [np.zeros((64, 64), np.uint8)]  # (the search would find nothing: any other message is the option's)
    refused(lambda: learn(black, names="a.png"), TypeError, "names")
    refused(lambda: learn(black, camera_height=-2.0), panomap.PanomapError, "camera height", "positive")
    refused(lambda: learn(black, model="poly"), panomap.PanomapError, "unknown radial model 'poly'")
    refused(lambda: learn(black, axis="sideways"), panomap.PanomapError, "axis")


def test_levelling_checks_the_table_and_the_pictures_size(chain) -> None:
    _, _, table = chain
    refused(lambda: panomap.level_table(table, "x.png"), TypeError, "pictures", "read_image")
    refused(lambda: panomap.level_table(table, [FRAME[:100, :100]]), panomap.PanomapError, "100 x 100", "160 x 160")


# Video, batches and rigs.


def test_a_video_run_checks_its_table_and_views_before_opening_the_video(chain, tmp_path) -> None:
    _, _, table = chain
    rig = panomap.CameraRig((table, table), ("cam0", "cam1"))
    output = panomap.ViewOutput(VIEW, tmp_path / "out.mp4")
    video = str(tmp_path / "in.mp4")  # (never opened: each call is refused first)
    refused(lambda: panomap.unwarp_video(rig, video, [output]), TypeError, "rig.tables[k]")
    refused(lambda: panomap.unwarp_video(table, video, []), panomap.PanomapError, "no view to write")
    refused(lambda: panomap.unwarp_video(table, video, [VIEW]), TypeError, "outputs[0]", "ViewOutput")
    refused(lambda: panomap.unwarp_video(table, video, [output], memory_limit=-1), panomap.PanomapError, "memory")
    assert not any(tmp_path.iterdir())


def test_video_and_batch_settings_are_checked_when_made() -> None:
    refused(lambda: panomap.Selection(every=1.5), panomap.PanomapError, "every", "whole")
    refused(lambda: panomap.Selection(start_s="1"), TypeError, "start")
    refused(lambda: panomap.EncoderSettings(crf=-5), panomap.PanomapError, "crf")
    refused(lambda: panomap.EncoderSettings(codec=5), TypeError, "codec")
    refused(lambda: panomap.EncoderSettings(bitrate=-1), panomap.PanomapError, "bit rate")
    refused(lambda: panomap.RunSettings(workers=0), panomap.PanomapError, "workers")
    refused(lambda: panomap.RunSettings(retries=-1), panomap.PanomapError, "retries")
    refused(lambda: panomap.RunSettings(segment_s=0), panomap.PanomapError, "segment_s")


def test_a_rig_is_made_of_tables_and_saved_as_a_rig(chain, tmp_path) -> None:
    _, _, table = chain
    refused(lambda: panomap.CameraRig(("a",), ("cam0",)), TypeError, "table", "load_table")
    refused(lambda: panomap.CameraRig((table, table), "ab"), TypeError, "names")
    refused(lambda: panomap.save_rig(table, tmp_path / "rig.npz"), TypeError, "the rig", "save_table")
    assert not any(tmp_path.iterdir())


CAMCHAIN = """cam0:
  camera_model: omni
  intrinsics: [0.9, 300.0, 300.0, 320.0, 240.0]
  distortion_model: radtan
  distortion_coeffs: [0.0, 0.0, 0.0, 0.0]
  resolution: [640, 480]
cam1:
  camera_model: omni
  intrinsics: [0.9, 300.0, 300.0, 320.0, 240.0]
  distortion_model: radtan
  distortion_coeffs: [0.0, 0.0, 0.0, 0.0]
  resolution: [640, 480]
  T_cn_cnm1:
  - [-1.0, 0.0, 0.0, 0.0]
  - [0.0, 1.0, 0.0, 0.0]
  - [0.0, 0.0, -1.0, 0.0]
  - [0.0, 0.0, 0.0, 1.0]
"""


def test_imports_check_their_numbers_before_reading(tmp_path) -> None:
    chain = tmp_path / "camchain.yaml"
    chain.write_text(CAMCHAIN)
    imported = panomap.import_calibration
    refused(lambda: imported(chain, camera="cam0", camera_position="0 0 0"), TypeError, "camera position")
    refused(lambda: imported(chain, camera="cam0", camera_position=(math.nan, 0, 0)), panomap.PanomapError, "finite")
    refused(lambda: imported(chain, camera="cam0", orientation_rad=(0, 0)), panomap.PanomapError, "orientation_rad")
    refused(lambda: imported(chain, camera="cam0", image_size="640x480"), TypeError, "image size")  # (was "6 x 4")
    refused(lambda: imported(chain, camera="cam0", sources=["a"]), TypeError, "sources")
    rig_of = panomap.rig_of_camchain
    refused(lambda: rig_of(chain, camera_position=(0, 0)), panomap.PanomapError, "camera position")
    refused(lambda: rig_of(chain, orientation_rad="0,0,0"), TypeError, "orientation_rad")
    refused(lambda: rig_of(chain, fov_rad=0), panomap.PanomapError, "fov_rad")
    refused(lambda: rig_of(chain, outer_radii=(100.0,)), panomap.PanomapError, "one outer radius")
    refused(lambda: rig_of(chain, flipped=5), panomap.PanomapError, "flipped")


def test_exports_and_batches_check_their_arguments(chain, tmp_path) -> None:
    _, _, table = chain
    rig = panomap.CameraRig((table, table), ("cam0", "cam1"))
    refused(lambda: panomap.export_calibration(rig, tmp_path / "x.txt", "ocam"), TypeError, "rig.tables[k]")
    picture = tmp_path / "in.png"
    panomap.write_image(picture, FRAME)
    panomap.save_table(table, tmp_path / "t.npz")
    refused(lambda: panomap.find_inputs(str(picture), tmp_path / "t.npz"), TypeError, "patterns", "list")
    found = panomap.find_inputs([str(picture)], str(tmp_path / "t.npz"))  # (a table's name as text: a path)
    assert [item.path for item in found] == [picture]
    refused(lambda: panomap.make_job(found, [VIEW], str(tmp_path / "{stem}.png")), TypeError, "NamedView")
    refused(lambda: panomap.NamedView("a", "panorama"), TypeError, "View", "parse_view_spec")
    refused(lambda: panomap.Settings(interpolation="bicubic"), panomap.PanomapError, "interpolation")
    refused(lambda: panomap.Settings(sampling="cubic"), panomap.PanomapError, "sampling")
    refused(lambda: panomap.read_image(picture, expected_size="160x160"), TypeError, "expected_size")


def test_a_file_name_that_is_none_or_an_array_is_named_as_such(chain, tmp_path) -> None:
    _, _, table = chain
    calls = [
        lambda: panomap.save_table(table, None),
        lambda: panomap.load_table(None),
        lambda: panomap.read_image(FRAME),  # (an image already: no file to read)
        lambda: panomap.write_image(None, FRAME),
        lambda: panomap.read_landmarks(3),
        lambda: panomap.load_rig(None),
    ]
    for call in calls:
        refused(call, TypeError, "a file name must be a str or a path")


def test_fit_options_that_are_no_numbers_are_named(chain) -> None:
    marks, _, _ = chain
    refused(lambda: panomap.fit_camera(marks, POSITION, (80, 79), pixel_sigma="1"), TypeError, "pixel sigma")
