"""A rig's video (issue 52, items 3 and 5): the fast blend equals RigRemapper's, the video's frames equal the
still command's, bad inputs are refused in one line before any work.

Ground truth as ``tests/test_rig.py``: ideal equidistant lenses chained in closed form (its helpers), the dual
fisheye back to back in one frame, the surround view four lenses turned by quarter turns, each its own picture.
"""

from __future__ import annotations

import math
from pathlib import Path

import av
import cv2
import numpy as np
import pytest

from panomap.interop.rig_of_camchain import rig_of_camchain
from panomap.rig import CameraRig, RigRemapper, camera_maps, save_rig
from panomap.rig.fast import FastRigRemapper
from panomap.views import EquirectView, FloorView
from test_orientation import conventions_axes
from test_rig import BACK_TO_BACK, HALF_FOV, SIDE, camchain, chain_truth, render_lens, textured_world

from helpers import assert_one_line_error, run

QUARTER = [[0, 0, -1, 1.0], [0, 1, 0, 0], [1, 0, 0, 1.0], [0, 0, 0, 1]]
LOSSLESS_BGR = ["--codec", "ffv1", "--pix-fmt", "bgr0"]


def noisy(picture: np.ndarray, seed: int, gain: float = 1.0) -> np.ndarray:
    """``picture`` times ``gain`` with sensor noise (sigma 2), as uint8."""
    rng = np.random.default_rng(seed)
    return np.clip(picture.astype(np.float32) * gain + rng.normal(0, 2, picture.shape), 0, 255).astype(np.uint8)


@pytest.fixture(scope="module")
def dual(tmp_path_factory: pytest.TempPathFactory) -> tuple[CameraRig, Path, np.ndarray]:
    """The back-to-back pair (its rig file) and one frame of a world through it, lens 1 12% brighter."""
    folder = tmp_path_factory.mktemp("rig_video")
    rig = rig_of_camchain(camchain(folder / "dual.yaml", [BACK_TO_BACK]), side_by_side=True, fov_rad=2 * HALF_FOV)
    save_rig(rig, folder / "dual.npz")
    truth = chain_truth(conventions_axes(0, 0, 0), np.zeros(3), [BACK_TO_BACK])
    world = textured_world()
    lenses = [render_lens(world, axes).astype(np.float32) for axes, _ in truth]
    frame = noisy(np.concatenate([lenses[0], lenses[1] * 1.12], axis=1), 1)
    return rig, folder / "dual.npz", frame


@pytest.fixture(scope="module")
def surround(tmp_path_factory: pytest.TempPathFactory) -> tuple[CameraRig, Path, list[np.ndarray]]:
    """Four lenses by quarter turns, camera 0 pitched 40 deg down from 1.2 m (its rig file), and one picture
    each of the world, camera 2 10% darker."""
    folder = tmp_path_factory.mktemp("rig_surround")
    rig = rig_of_camchain(camchain(folder / "car.yaml", [QUARTER] * 3), orientation_rad=(0.0, math.radians(-40), 0.0),
                          camera_position=(1.0, 0.0, 1.2))  # fmt: skip
    save_rig(rig, folder / "car.npz")
    truth = chain_truth(conventions_axes(0, -40, 0), np.array([1.0, 0.0, 1.2]), [QUARTER] * 3)
    world = textured_world(2)
    pictures = [noisy(render_lens(world, axes), k, 0.9 if k == 2 else 1.0) for k, (axes, _) in enumerate(truth)]
    return rig, folder / "car.npz", pictures


def test_the_fast_blend_equals_the_rig_remapper_on_a_dual_fisheye_frame(dual: tuple) -> None:  # type: ignore[type-arg]
    """One frame holding both lenses, equirect (wrapping weights), colour and grey, with the gains found and
    with none: the fast blend (one remap, the band blended apart, gains as lookup tables) is RigRemapper's
    picture within 1 grey level (the same float maps and float32 sums: measured equal), and finds its gains."""
    rig, _, frame = dual
    remapper = RigRemapper(rig, camera_maps(rig, EquirectView(size=(512, 256))), wrap=True)
    fast = FastRigRemapper(remapper)
    gains = remapper.gains(frame)
    assert np.allclose(fast.gains(frame), gains, rtol=1e-5)
    assert 1.09 < float(np.mean(gains[0] / gains[1])) < 1.15
    for given in (gains, np.ones_like(gains)):
        assert np.abs(fast(frame, given).astype(int) - remapper(frame, given)).max() <= 1
    grey = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
    fast_grey = FastRigRemapper(remapper, channels=1)
    assert np.abs(fast_grey(grey, gains[:, :1]).astype(int) - remapper(grey, gains[:, :1])).max() <= 1
    assert 0.05 < fast.plane.band_size / (512 * 256) < 0.3  # (the band: the 10 deg overlap, wider at the poles)


def test_the_fast_blend_equals_the_rig_remapper_on_a_surround_floor(surround: tuple) -> None:  # type: ignore[type-arg]
    """Four pictures, a floor map (its weights do not wrap), nearest and linear: within 1 grey level (nearest: but
    for the odd pixel whose entry lies a hair from a pixel's edge, where the fast buffer's offset, added in float32
    at u ~ 3000, rounds it across the tie: at most 0.2% of pixels)."""
    rig, _, pictures = surround
    maps = camera_maps(rig, FloorView(0.0, (-3.0, 5.0), (-4.0, 4.0), (160, 160)))
    for interpolation in ("linear", "nearest"):
        remapper = RigRemapper(rig, maps, interpolation)
        gains = remapper.gains(pictures)
        off = np.abs(FastRigRemapper(remapper)(pictures, gains).astype(int) - remapper(pictures, gains)).max(axis=-1)
        assert off.max() <= 1 if interpolation == "linear" else np.mean(off > 1) <= 0.002


def write_video(path: Path, frames: list[np.ndarray], lossless: bool = True) -> None:
    """``frames`` (BGR) as a video: FFV1 bgr0 (lossless) or H.264 yuv420p."""
    with av.open(str(path), "w") as container:
        stream = container.add_stream("ffv1" if lossless else "libx264", rate=25)
        stream.height, stream.width = frames[0].shape[:2]
        stream.pix_fmt = "bgr0" if lossless else "yuv420p"
        if not lossless:
            stream.options = {"preset": "ultrafast", "crf": "14"}
        for frame in frames:
            for packet in stream.encode(av.VideoFrame.from_ndarray(frame, format="bgr24")):
                container.mux(packet)
        for packet in stream.encode(None):
            container.mux(packet)


def frames_of(path: Path) -> list[np.ndarray]:
    with av.open(str(path)) as container:
        return [frame.to_ndarray(format="bgr24") for frame in container.decode(video=0)]


def test_the_videos_first_frame_is_the_still_commands_picture(dual: tuple, tmp_path: Path) -> None:  # type: ignore[type-arg]
    """A lossless dual-fisheye video of three frames: its first blended frame equals ``panomap equirect`` of that
    frame within 1 grey level (the same blend, BGR throughout); through H.264 and yuv420p (blended plane by plane,
    the luma's gain for all three), within 4 on average (the codecs' loss, and the chroma's gain about grey)."""
    _, rig_path, frame = dual
    write_video(tmp_path / "dual.mkv", [frame, np.roll(frame, 3, axis=0), frame])
    cv2.imwrite(str(tmp_path / "frame.png"), frame)
    still = run("equirect", rig_path, tmp_path / "frame.png", "-o", tmp_path / "still.png", "--size", "512x256")
    assert still.exit_code == 0, still.output
    expected = cv2.imread(str(tmp_path / "still.png")).astype(int)
    result = run("video", rig_path, tmp_path / "dual.mkv", "-o", tmp_path / "e.mkv", "--view",
                 "equirect:size=512x256", *LOSSLESS_BGR)  # fmt: skip
    assert result.exit_code == 0, result.output
    assert "blended 2 cameras' view: 3 frames" in result.output
    blended = frames_of(tmp_path / "e.mkv")
    assert len(blended) == 3
    assert np.abs(blended[0] - expected).max() <= 1
    write_video(tmp_path / "dual.mp4", [frame, frame], lossless=False)
    assert run("video", rig_path, tmp_path / "dual.mp4", "-q", "-o", tmp_path / "e.mp4", "--view",
               "equirect:size=512x256").exit_code == 0  # fmt: skip
    assert float(np.abs(frames_of(tmp_path / "e.mp4")[0] - expected).mean()) < 4


def test_four_videos_are_read_in_step_to_the_shortest(surround: tuple, tmp_path: Path) -> None:  # type: ignore[type-arg]
    """One video per camera, one of them a frame shorter: the floor map's video has the shortest's frames, and
    its first frame is the still command's."""
    _, rig_path, pictures = surround
    videos = []
    for k, picture in enumerate(pictures):
        videos.append(tmp_path / f"cam{k}.mkv")
        write_video(videos[-1], [picture] * (2 if k == 1 else 3))
        cv2.imwrite(str(tmp_path / f"cam{k}.png"), picture)
    spec = "floor:z=0,x=-3:5,y=-4:4,size=160x160"
    result = run("video", rig_path, *videos, "-o", tmp_path / "floor.mkv", "--view", spec, *LOSSLESS_BGR)
    assert result.exit_code == 0, result.output
    blended = frames_of(tmp_path / "floor.mkv")
    assert len(blended) == 2
    still = run("floor", rig_path, *(tmp_path / f"cam{k}.png" for k in range(4)), "-o", tmp_path / "floor.png",
                "--z", "0", "--x", "-3", "5", "--y", "-4", "4", "--size", "160x160")  # fmt: skip
    assert still.exit_code == 0, still.output
    assert np.abs(blended[0].astype(int) - cv2.imread(str(tmp_path / "floor.png"))).max() <= 1


def test_bad_inputs_are_refused_in_one_line_before_any_work(dual: tuple, surround: tuple, tmp_path: Path) -> None:  # type: ignore[type-arg]
    """Two videos for a rig whose cameras share one frame, three for four cameras, a video of the wrong size,
    cubic reading and two views: one line each, no output written."""
    _, rig_path, frame = dual
    _, car_path, _ = surround
    write_video(tmp_path / "dual.mkv", [frame])
    write_video(tmp_path / "half.mkv", [frame[:, :SIDE]])
    out = tmp_path / "out.mkv"
    view = ["--view", "equirect:size=256x128"]
    assert_one_line_error(run("video", rig_path, tmp_path / "dual.mkv", tmp_path / "dual.mkv", "-o", out, *view),
                          "share one frame", "not 2", exit_code=2)  # fmt: skip
    assert_one_line_error(run("video", car_path, *[tmp_path / "dual.mkv"] * 3, "-o", out, *view),
                          "one video per camera", "cam0, cam1, cam2, cam3", "not 3", exit_code=2)  # fmt: skip
    assert_one_line_error(run("video", rig_path, tmp_path / "half.mkv", "-o", out, *view),
                          "half.mkv", f"its frames are {SIDE} x {SIDE}", f"{2 * SIDE} x {SIDE}")  # fmt: skip
    assert_one_line_error(run("video", car_path, *[tmp_path / "dual.mkv"] * 4, "-o", out, *view),
                          "camera cam0 is 960 x 960")  # fmt: skip
    assert_one_line_error(run("video", rig_path, tmp_path / "dual.mkv", "-o", out, *view, "--interp", "cubic"),
                          "linear or nearest", exit_code=2)  # fmt: skip
    assert_one_line_error(run("video", rig_path, tmp_path / "dual.mkv", "-o", "o_{name}.mkv", *view, "--view",
                              "panorama:size=256x64"), "one view", exit_code=2)  # fmt: skip
    assert not out.exists() and not [p for p in tmp_path.iterdir() if ".part" in p.name]
